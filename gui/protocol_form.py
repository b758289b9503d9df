"""A protocol file as a form: one entry per step parameter, validated as you type.

Validation is the CLI's own: each entry through its step kind's :class:`Field` (range,
units), then the whole edited table through :func:`parse_protocol` (cross-field checks, step
kinds, the rig). The message sits beside the offending entry; the edited table is what runs
and is stored beside the data.
"""

from __future__ import annotations

import copy
import html
import math
from dataclasses import dataclass
from typing import Any

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QGridLayout,
    QGroupBox,
    QLabel,
    QLineEdit,
    QVBoxLayout,
    QWidget,
)

from gelrig.gui.fmt import entry_text, entry_value, quantity
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import REQUIRED, Field, Where, written_unit
from gelrig.instrument.core.units import convert
from gelrig.protocols.sample import SampleSizeMissing
from gelrig.protocols.spec import ProtocolSpec, parse_protocol
from gelrig.protocols.steps import KINDS

#: Parameters that are lists (not Fields of their step kind), validated by the step itself.
LIST_KEYS = {"speed_ladder": ("speeds",)}
_ERROR = "color:#c62828;"


@dataclass
class Entry:
    """One editable parameter of one step."""

    step: int
    key: str
    field: Field | None
    edit: QLineEdit
    error: QLabel
    is_list: bool = False
    unit: QLabel | None = None

    def shown_unit(self) -> str:
        """The unit the entry is read in: the one typed ('0.5 mm/s'); for an empty entry the
        unit its default is shown in (the placeholder's, 'default 0.5 mm' beside 'mm'); for a
        bare number the field's SI unit, which is how the protocol file reads it."""
        if self.field is None:
            return ""
        text = self.edit.text().strip()
        if not text:
            return _default_unit(self.field)
        typed = None if isinstance(entry_value(text), int | float) else written_unit(text)
        return typed or self.field.unit

    def show_unit(self) -> None:
        """Beside the entry: the unit its value is in; in its tooltip, the allowed range in
        that unit (what the protocol file uses, not SI)."""
        if self.field is None or self.unit is None:
            return
        unit = self.shown_unit()
        self.unit.setText(unit)
        tip = self.field.allowed(unit)
        self.edit.setToolTip(f"{self.field.help}\n{tip}" if self.field.help else tip)

    @property
    def name(self) -> str:
        return Where(f"step[{self.step}]").name(self.key)

    def value(self) -> Any:
        text = self.edit.text().strip()
        if self.is_list:
            return [entry_value(part) for part in text.split(",") if part.strip()]
        return entry_value(text)

    def set_error(self, message: str) -> None:
        self.error.setText(message)
        self.error.setVisible(bool(message))


def _default_unit(f: Field) -> str:
    """The unit :func:`_placeholder` shows the default in (the SI unit if it shows none)."""
    if f.display and f.unit:
        return f.display
    if f.default is None or f.default is REQUIRED or not f.unit or not math.isfinite(f.default):
        return f.unit
    shown = quantity(f.default, f.unit).split(" ", 1)
    return shown[1] if len(shown) == 2 else f.unit


def _placeholder(f: Field | None) -> str:
    if f is None or f.default is None:
        return "required" if f is not None else "default"
    if math.isnan(f.default):
        return "from an earlier step"
    if f.display and f.unit:
        return f"default {convert(f.default, f.unit, f.display):g} {f.display}"
    return f"default {quantity(f.default, f.unit) if f.unit else f'{f.default:g}'}"


class ProtocolForm(QWidget):
    """Entries for every step's parameters; ``spec`` is the validated protocol or None."""

    changed = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.layout_ = QVBoxLayout(self)
        self.header = QLabel("open a protocol file")
        self.header.setWordWrap(True)
        self.general = QLabel()
        self.general.setStyleSheet(_ERROR)
        self.general.setWordWrap(True)
        self.layout_.addWidget(self.header)
        self.layout_.addWidget(self.general)
        self.boxes: list[QGroupBox] = []
        self.entries: list[Entry] = []
        self.table: dict[str, Any] = {}
        self.source = "<protocol>"
        self.spec: ProtocolSpec | None = None
        self.errors: list[str] = []
        #: the run's ``[sample]`` table from the window's Sample fields, replacing the file's
        #: ({}: no sample given); None keeps the file's
        self.sample_table: dict[str, Any] | None = None
        #: the protocol refused for a size of the sample nobody gave (None: not so)
        self.missing: SampleSizeMissing | None = None

    def entry(self, step: int, key: str) -> Entry:
        for e in self.entries:
            if e.step == step and e.key == key:
                return e
        raise KeyError(Where(f"step[{step}]").name(key))

    def set_table(self, table: dict[str, Any], source: str) -> None:
        """Show a protocol file's table (from TOML) for editing."""
        self.table, self.source = copy.deepcopy(table), source
        for box in self.boxes:
            box.deleteLater()
        self.boxes.clear()
        self.entries.clear()
        head = table.get("protocol", {}) if isinstance(table.get("protocol"), dict) else {}
        name = html.escape(str(head.get("name", "(no name)")))
        self.header.setText(f"<b>{name}</b> — {html.escape(str(head.get('rig', '?')))} rig"
                            f"<br>{html.escape(source)}")
        steps = table.get("step", [])
        for i, raw in enumerate(steps if isinstance(steps, list) else []):
            if isinstance(raw, dict):
                self._add_step(i, raw)
        self.validate()

    def _add_step(self, i: int, raw: dict[str, Any]) -> None:
        kind = raw.get("kind")
        definition = KINDS.get(kind) if isinstance(kind, str) else None
        default = definition.description if definition is not None else kind
        box = QGroupBox(f"{i}. {raw.get('name', default)} [{kind}]")
        grid = QGridLayout(box)
        self.layout_.addWidget(box)
        self.boxes.append(box)
        if definition is None:
            grid.addWidget(QLabel("unknown step kind: nothing to edit"), 0, 0)
            return
        keys: list[tuple[str, Field | None, bool]] = [(f.key, f, False)
                                                      for f in definition.fields]
        keys += [(k, None, True) for k in LIST_KEYS.get(definition.kind, ())]
        for row, (key, f, is_list) in enumerate(keys):
            label = QLabel(key)
            edit = QLineEdit(entry_text(raw[key]) if key in raw else "")
            edit.setObjectName(f"step{i}_{key}")
            edit.setPlaceholderText(_placeholder(f))
            unit = QLabel(f.unit if f is not None else ("list, m/s" if is_list else ""))
            error = QLabel()
            error.setStyleSheet(_ERROR)
            error.setWordWrap(True)
            error.setVisible(False)
            if f is not None:
                tip = f"{f.help}\n{f.allowed()}" if f.help else f.allowed()
            else:  # a list the step checks item by item (each within its field's range)
                tip = (f"{key}: a comma-separated list, each in m/s or with its unit "
                       "(1e-4 m/s, 0.1 mm/s)" if is_list else key)
            label.setToolTip(tip)
            edit.setToolTip(tip)
            grid.addWidget(label, 2 * row, 0)
            grid.addWidget(edit, 2 * row, 1)
            grid.addWidget(unit, 2 * row, 2)
            grid.addWidget(error, 2 * row + 1, 1, 1, 2)
            entry = Entry(i, key, f, edit, error, is_list, unit)
            entry.show_unit()
            edit.textChanged.connect(self.validate)
            self.entries.append(entry)

    def edited_table(self) -> dict[str, Any]:
        """The protocol table with the entries applied (an empty entry: the default)."""
        table = copy.deepcopy(self.table)
        if self.sample_table is not None and table:
            if self.sample_table:
                table["sample"] = copy.deepcopy(self.sample_table)
            else:
                table.pop("sample", None)
        steps = table.get("step", [])
        for e in self.entries:
            raw = steps[e.step]
            if e.edit.text().strip():
                raw[e.key] = e.value()
            else:
                raw.pop(e.key, None)
        return table

    def validate(self) -> None:
        """Check every entry, then the whole protocol; show messages; emit ``changed``."""
        self.errors = []
        for e in self.entries:
            message = ""
            e.show_unit()
            if e.field is not None and e.edit.text().strip():
                try:
                    e.field.parse(e.value(), Where(f"step[{e.step}]"))
                except ConfigError as exc:
                    message = exc.allowed
            e.set_error(message)
            if message:
                self.errors.append(f"{e.name}: {message}")
        table = self.edited_table()
        self.spec, self.missing = None, None
        self.general.setText("")
        try:
            spec = parse_protocol(table, self.source)
        except SampleSizeMissing as exc:  # refused as the run would be (the CLI's line)
            if not self.errors:
                self._place(exc)
                self.errors.append(str(exc))
                self.missing = exc
        except ConfigError as exc:
            if not self.errors:
                self._place(exc)
                self.errors.append(str(exc))
        else:
            if not self.errors:
                self.spec = spec
        self.changed.emit()

    def _place(self, exc: ConfigError) -> None:
        """Put a whole-protocol error beside its entry if it names one, else on top."""
        for e in self.entries:
            if exc.field == e.name or exc.field.startswith(f"{e.name}["):
                e.set_error(exc.allowed)
                return
        self.general.setText(str(exc))
