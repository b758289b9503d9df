"""The run's sample in the window (docs/decisions/0280): its name, the sizes the steps take
from it (the compression sphere's diameter; the shear spheres' r1 and r2) and its material.

What the fields show is what the run uses: it replaces a protocol file's ``[sample]`` (as
``gelrig run --sample`` does), Save writes it as the file's ``[sample]``, run.json records
it. The fields are validated as the protocol file's table is (the :class:`Sample`'s fields:
unit, range) and remembered per rig kind between runs and window restarts (QSettings).
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import QSettings, Signal
from PySide6.QtWidgets import QGridLayout, QGroupBox, QLabel, QLineEdit, QWidget

from gelrig.gui.fmt import entry_text, entry_value
from gelrig.gui.protocol_form import Entry
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import Field, Text, Where
from gelrig.instrument.core.units import convert
from gelrig.protocols.sample import Sample

#: The sizes each rig kind's steps take from the sample.
SIZES: dict[str, tuple[str, ...]] = {"compression": ("diameter",), "shear": ("r1", "r2")}
#: The rows of the group, in order.
KEYS = ("name", "diameter", "r1", "r2", "material")
_WHERE = Where("sample")
_ERROR = "color:#c62828;"


class SizeEntry(Entry):
    """A size of the sample, read and shown as a step parameter's entry is."""

    @property
    def name(self) -> str:
        return _WHERE.name(self.key)


def field_text(value: object, spec: Field | None) -> str:
    """A ``[sample]`` value as a field's text: a size held in SI (run.json, a script's sample)
    in the unit people read it in (``0.012`` -> ``12 mm``); a written one as written."""
    if spec is not None and isinstance(value, int | float) and not isinstance(value, bool):
        return f"{convert(float(value), spec.unit, spec.display):g} {spec.display}"
    return "" if value is None else entry_text(value)


class SampleForm(QGroupBox):
    """Name, the rig kind's sizes, material; ``sample`` is what the run uses (None: none
    given), ``errors`` the fields' one-line errors."""

    changed = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Sample", parent)
        self.setToolTip("the sample on the rig: it replaces the protocol file's [sample] "
                        "(as gelrig run --sample does); Save writes it into the file")
        grid = QGridLayout(self)
        grid.setContentsMargins(6, 4, 6, 4)
        grid.setVerticalSpacing(2)
        specs = Sample.specs()
        self.kind = "compression"
        #: the fields' texts of each rig kind (what is remembered)
        self.texts: dict[str, dict[str, str]] = {k: {} for k in SIZES}
        self.edits: dict[str, QLineEdit] = {}
        self.labels: dict[str, QLabel] = {}
        self.sizes: dict[str, SizeEntry] = {}
        self.sample: Sample | None = None
        self.errors: list[str] = []
        self.needed: dict[str, str] = {}  # size -> why a step needs it (none given)
        for row, key in enumerate(KEYS):
            spec = specs[key]
            label = QLabel(key)
            edit = QLineEdit()
            edit.setObjectName(f"sample_{key}")
            grid.addWidget(label, 2 * row, 0)
            grid.addWidget(edit, 2 * row, 1)
            self.edits[key], self.labels[key] = edit, label
            if isinstance(spec, Field):
                unit = QLabel(spec.display)
                error = QLabel()
                error.setStyleSheet(_ERROR)
                error.setWordWrap(True)
                error.setVisible(False)
                grid.addWidget(unit, 2 * row, 2)
                grid.addWidget(error, 2 * row + 1, 1, 1, 2)
                edit.setPlaceholderText("not given")
                entry = SizeEntry(-1, key, spec, edit, error, False, unit)
                entry.show_unit()
                label.setToolTip(edit.toolTip())
                self.sizes[key] = entry
            else:
                assert isinstance(spec, Text)
                edit.setPlaceholderText({"name": "what the sample is",
                                         "material": "recipe, cure, batch"}[key])
                edit.setToolTip(f"{spec.help} (text)")
                label.setToolTip(edit.toolTip())
            edit.textChanged.connect(self._edited)
        self._show_rows()
        self._edited()

    # ---- what is shown --------------------------------------------------------------------
    def set_kind(self, kind: str | None) -> None:
        """Show the sizes of ``kind``'s rig (its fields as last left for that kind)."""
        kind = kind if kind in SIZES else "compression"
        if kind == self.kind:
            return
        self.texts[self.kind] = self.current()
        self.kind = kind
        self._fill(self.texts[kind])

    def set_table(self, table: object) -> None:
        """Fill the fields from a protocol file's (or a script's) ``[sample]`` table."""
        raw = table if isinstance(table, dict) else {}
        specs = Sample.specs()
        texts = {}
        for key in KEYS:
            spec = specs[key]
            texts[key] = field_text(raw.get(key), spec if isinstance(spec, Field) else None)
        self._fill(texts)

    def set_texts(self, texts: dict[str, dict[str, str]]) -> None:
        """The remembered fields of every kind (those of the kind shown go in its fields)."""
        for kind in SIZES:
            self.texts[kind] = {k: str(v) for k, v in texts.get(kind, {}).items() if k in KEYS}
        self._fill(self.texts[self.kind])

    def current(self) -> dict[str, str]:
        return {key: edit.text() for key, edit in self.edits.items() if edit.text().strip()}

    def all_texts(self) -> dict[str, dict[str, str]]:
        self.texts[self.kind] = self.current()
        return {kind: dict(texts) for kind, texts in self.texts.items()}

    def _fill(self, texts: dict[str, str]) -> None:
        for key, edit in self.edits.items():
            edit.blockSignals(True)
            edit.setText(texts.get(key, ""))
            edit.blockSignals(False)
        self._show_rows()
        self._edited()

    def _show_rows(self) -> None:
        """The kind's sizes, and any other size that holds a value (nothing given is hidden)."""
        for key in self.sizes:
            visible = key in SIZES[self.kind] or bool(self.edits[key].text().strip())
            for widget in (self.labels[key], self.edits[key], self.sizes[key].unit):
                if widget is not None:
                    widget.setVisible(visible)
            if not visible:
                self.sizes[key].set_error("")

    # ---- what the run uses ------------------------------------------------------------------
    def table(self) -> dict[str, Any]:
        """The ``[sample]`` table the fields give (sizes as typed, ``"12 mm"``); {} if none."""
        out: dict[str, Any] = {}
        for key, edit in self.edits.items():
            text = edit.text().strip()
            if text:
                out[key] = entry_value(text) if key in self.sizes else text
        return out

    def set_needed(self, needed: dict[str, str]) -> None:
        """Sizes a step needs that no field gives: said beside their (empty) fields."""
        self.needed = needed
        self._show_errors()

    def _edited(self, _text: str = "") -> None:
        self.errors, self.sample = [], None
        for entry in self.sizes.values():
            entry.show_unit()
            self.labels[entry.key].setToolTip(entry.edit.toolTip())
        table = self.table()
        try:
            self.sample = Sample.from_table(table, "sample") if table else None
        except ConfigError as exc:
            self.errors.append(str(exc))
        self._show_errors()
        self.changed.emit()

    def _show_errors(self) -> None:
        for key, entry in self.sizes.items():
            message = ""
            if entry.edit.text().strip():
                try:
                    entry.field.parse(entry.value(), _WHERE)  # type: ignore[union-attr]
                except ConfigError as exc:
                    message = exc.allowed
            elif key in self.needed:
                message = self.needed[key]
            entry.set_error(message)


def load_texts(store: QSettings) -> dict[str, dict[str, str]]:
    """The sample fields remembered for each rig kind."""
    out: dict[str, dict[str, str]] = {}
    for kind in SIZES:
        texts = {}
        for key in KEYS:
            value = store.value(f"sample/{kind}/{key}")
            if isinstance(value, str) and value.strip():
                texts[key] = value
        out[kind] = texts
    return out


def save_texts(store: QSettings, texts: dict[str, dict[str, str]]) -> None:
    """Remember the sample fields of each rig kind (an empty field is forgotten)."""
    for kind in SIZES:
        for key in KEYS:
            value = texts.get(kind, {}).get(key, "")
            if value.strip():
                store.setValue(f"sample/{kind}/{key}", value)
            else:
                store.remove(f"sample/{kind}/{key}")
