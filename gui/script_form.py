"""A protocol script (``.py``, docs/scripting.md) in the window: its parameters, read from
its function's signature, as fields holding TOML values (``0.04``, ``"600 s"``,
``[0.02, 0.04]``: what ``gelrig run x.py --param`` takes); the script with those values is
what Run and the rehearsal (the plan of a script) run."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QFormLayout, QLabel, QLineEdit, QVBoxLayout, QWidget

from gelrig.gui.tomlout import value_text
from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.resolve import parse_params
from gelrig.protocols.script import Script


class ScriptForm(QWidget):
    """One field per parameter of the script's function (after ``run``), its default shown;
    ``script`` is the script called with the fields' values, or None with ``errors``."""

    changed = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        layout = QVBoxLayout(self)
        self.head = QLabel("")
        self.head.setWordWrap(True)
        layout.addWidget(self.head)
        self.fields_box = QWidget()
        self.fields = QFormLayout(self.fields_box)
        layout.addWidget(self.fields_box)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color:#b00020;")
        layout.addWidget(self.message)
        layout.addStretch(1)
        self.base: Script | None = None
        self.script: Script | None = None
        self.errors: list[str] = []
        self.entries: dict[str, QLineEdit] = {}

    def set_script(self, script: Script) -> None:
        """Show ``script``'s parameters with their defaults (or the values it was given)."""
        self.base = script
        while self.fields.rowCount():
            self.fields.removeRow(0)
        self.entries = {}
        given = dict(script.params)
        for name, default in script.parameters().items():
            entry = QLineEdit(value_text(given[name]) if name in given else
                              "" if default is None else value_text(default))
            entry.setObjectName(f"param_{name}")
            entry.setToolTip(f"script parameter {name}: a TOML value (0.04, \"600 s\", "
                             f"[0.02, 0.04]); default "
                             f"{'none (required)' if default is None else value_text(default)}"
                             "; the step kinds check units and ranges as the script runs")
            entry.textChanged.connect(self._edited)
            self.fields.addRow(name, entry)
            self.entries[name] = entry
        doc = f"<br>{script.description}" if script.description else ""
        count = len(self.entries)
        self.head.setText(f"<b>{script.name}</b> — {script.rig} rig script, "
                          f"{count} parameter{'s' if count != 1 else ''}{doc}<br>"
                          "its steps are decided as it runs: the plan is its rehearsal")
        self._edited()

    def _edited(self, _text: str = "") -> None:
        self.script, self.errors = None, []
        if self.base is not None:
            texts = [f"{name}={entry.text()}" for name, entry in self.entries.items()
                     if entry.text().strip()]
            try:
                self.script = self.base.with_params(**parse_params(texts))
            except ConfigError as exc:
                self.errors = [str(exc)]
        self.message.setText("; ".join(self.errors))
        self.changed.emit()
