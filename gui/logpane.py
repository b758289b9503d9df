"""The log pane: the run's story (states, steps, faults) and the library's log records,
from any thread."""

from __future__ import annotations

import contextlib
import logging
import time

from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtWidgets import QPlainTextEdit, QWidget


class LogPane(QPlainTextEdit):
    """Read-only, bounded, newest at the bottom."""

    def __init__(self, parent: QWidget | None = None, max_lines: int = 5000):
        super().__init__(parent)
        self.setReadOnly(True)
        self.setMaximumBlockCount(max_lines)
        self.setPlaceholderText("log")

    def add(self, text: str, level: str = "info") -> None:
        stamp = time.strftime("%H:%M:%S")
        mark = "" if level == "info" else f"{level.upper()}: "
        self.appendPlainText(f"{stamp}  {mark}{text}")


class _Emitter(QObject):
    record = Signal(str, str)


class QtLogHandler(logging.Handler):
    """A logging handler that hands records to a LogPane on the GUI thread (queued)."""

    def __init__(self, pane: LogPane, level: int = logging.INFO):
        super().__init__(level)
        self.emitter = _Emitter()
        self.emitter.record.connect(pane.add, Qt.ConnectionType.QueuedConnection)
        self.setFormatter(logging.Formatter("%(name)s: %(message)s"))

    def emit(self, record: logging.LogRecord) -> None:
        with contextlib.suppress(RuntimeError):  # the pane is gone (window closed)
            self.emitter.record.emit(self.format(record), record.levelname.lower())
