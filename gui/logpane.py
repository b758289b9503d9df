"""The log pane: the run's story (states, steps, faults) and the library's log records,
from any thread."""

from __future__ import annotations

import contextlib
import logging
import time
from pathlib import Path

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
        self._last = ("", 0.0)

    def emit(self, record: logging.LogRecord) -> None:
        """One line per record of the window's own (``gelrig.gui``: one per fault, in
        words): its message's first line, no traceback; the same line again within
        :data:`REPEAT_S` is dropped. The library's records (the way a fault unfolds, call
        by call) go to the log files only, unless critical."""
        if not record.name.startswith("gelrig.gui") and record.levelno < logging.CRITICAL:
            return
        text = record.getMessage()
        line = f"{record.name}: {text.splitlines()[0] if text else ''}"
        now = time.monotonic()
        if self._last[0] == line and now - self._last[1] < REPEAT_S:
            return
        self._last = (line, now)
        with contextlib.suppress(RuntimeError):  # the pane is gone (window closed)
            self.emitter.record.emit(line, record.levelname.lower())


#: The log pane drops a record that repeats the previous line within this time (s).
REPEAT_S = 30.0


def file_log(folder: Path) -> tuple[logging.Handler, Path] | None:
    """The window's log file ``folder/gelrig-gui.log``: every record at WARNING and up,
    and the GUI's own DEBUG records (the tracebacks the log pane leaves out); None if
    the folder cannot be written."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / "gelrig-gui.log"
        handler = logging.FileHandler(path, encoding="utf-8")
    except OSError:
        return None
    handler.setLevel(logging.DEBUG)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logging.getLogger("gelrig.gui").setLevel(logging.DEBUG)
    return handler, path
