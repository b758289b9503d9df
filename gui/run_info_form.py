"""Who runs the next run and why (ADR 0370): the operator, a note and tags, above Run.

The fields are checked as ``gelrig run --operator --note --tag`` checks them
(:func:`gelrig.protocols.runinfo.run_info`: one line each; a bad value is said under the
field and keeps Run disabled), go into run.json through the same ``create_run`` as the CLI's,
and are remembered between runs and window restarts (QSettings). Tags are typed comma-
separated (``week48, fresh batch``).
"""

from __future__ import annotations

from PySide6.QtCore import QSettings, Signal
from PySide6.QtWidgets import QGridLayout, QGroupBox, QLabel, QLineEdit, QWidget

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.runinfo import RunInfo, run_info

#: The fields, in order: key, placeholder, tooltip.
FIELDS = (("operator", "who runs it", "the operator's name (gelrig run --operator)"),
          ("note", "why, what is special", "one line about this run (gelrig run --note)"),
          ("tags", "week48, fresh batch", "tags, comma-separated (gelrig run --tag, one per "
                                          "tag); gelrig runs --tag finds the run by them"))
_ERROR = "color:#c62828;"


def split_tags(text: str) -> list[str]:
    """``"a, b ,,c"`` -> ``["a", "b", "c"]``."""
    return [part.strip() for part in text.split(",") if part.strip()]


class RunInfoForm(QGroupBox):
    """Operator, note, tags; ``info`` is what the run records (None while a field is bad),
    ``errors`` the fields' one-line errors."""

    changed = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Run record", parent)
        self.setToolTip("stored in run.json with the run; gelrig runs and the Results tab "
                        "list and filter runs by them")
        grid = QGridLayout(self)
        grid.setContentsMargins(6, 4, 6, 4)
        grid.setVerticalSpacing(2)
        self.edits: dict[str, QLineEdit] = {}
        self.error = QLabel()
        self.error.setStyleSheet(_ERROR)
        self.error.setWordWrap(True)
        self.error.setVisible(False)
        for row, (key, placeholder, tip) in enumerate(FIELDS):
            label = QLabel(key)
            edit = QLineEdit()
            edit.setObjectName(f"run_{key}")
            edit.setPlaceholderText(placeholder)
            edit.setToolTip(tip)
            label.setToolTip(tip)
            grid.addWidget(label, row, 0)
            grid.addWidget(edit, row, 1)
            edit.textChanged.connect(self._edited)
            self.edits[key] = edit
        grid.addWidget(self.error, len(FIELDS), 0, 1, 2)
        self.info: RunInfo | None = RunInfo()
        self.errors: list[str] = []

    def texts(self) -> dict[str, str]:
        return {key: edit.text() for key, edit in self.edits.items()}

    def set_texts(self, texts: dict[str, str]) -> None:
        for key, edit in self.edits.items():
            edit.setText(texts.get(key, ""))

    def _edited(self, _text: str = "") -> None:
        texts = self.texts()
        try:
            self.info = run_info(texts["operator"].strip() or None, texts["note"],
                                 split_tags(texts["tags"]), option="")
            self.errors = []
        except ConfigError as exc:
            self.info, self.errors = None, [str(exc)]
        self.error.setText("; ".join(self.errors))
        self.error.setVisible(bool(self.errors))
        self.changed.emit()


def load_info(store: QSettings) -> dict[str, str]:
    """The fields as last used."""
    out = {}
    for key, *_ in FIELDS:
        value = store.value(f"run/{key}")
        if isinstance(value, str):
            out[key] = value
    return out


def save_info(store: QSettings, texts: dict[str, str]) -> None:
    """Remember the fields (an empty one is forgotten)."""
    for key, *_ in FIELDS:
        value = texts.get(key, "")
        if value.strip():
            store.setValue(f"run/{key}", value)
        else:
            store.remove(f"run/{key}")
