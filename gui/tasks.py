"""One thread that owns the rig: every instrument call runs on it, one at a time.

The drivers are not thread-safe (one transport, one reply at a time), so connecting, the idle
readouts, manual moves and the protocol run itself all go through this queue; the GUI thread
never touches an instrument and never blocks on one. A stop jumps the queue. Results and
errors come back to the GUI thread through a queued Qt signal.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from PySide6.QtCore import QObject, Qt, Signal

log = logging.getLogger(__name__)

Done = Callable[[Any], None]
Failed = Callable[[BaseException], None]


@dataclass
class _Task:
    fn: Callable[[], Any]
    done: Done | None
    failed: Failed | None


class RigThread(QObject):
    """A single worker thread with a FIFO queue (urgent tasks first), callbacks on the GUI
    thread."""

    _deliver = Signal(object, object)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._deliver.connect(self._on_deliver, Qt.ConnectionType.QueuedConnection)
        self._queue: deque[_Task] = deque()
        self._cond = threading.Condition()
        self._busy = False
        self._closing = False
        self._thread = threading.Thread(target=self._loop, name="gelrig-rig", daemon=True)
        self._thread.start()

    def submit(self, fn: Callable[[], Any], done: Done | None = None,
               failed: Failed | None = None, urgent: bool = False) -> bool:
        """Queue ``fn``; False if the thread is shutting down."""
        task = _Task(fn, done, failed)
        with self._cond:
            if self._closing:
                return False
            if urgent:
                self._queue.appendleft(task)
            else:
                self._queue.append(task)
            self._cond.notify()
        return True

    @property
    def idle(self) -> bool:
        with self._cond:
            return not self._busy and not self._queue

    def shutdown(self, timeout: float = 30.0) -> bool:
        """Run what is queued, then end the thread; True if it ended within ``timeout``."""
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closing:
                    self._cond.wait()
                if not self._queue:
                    return
                task = self._queue.popleft()
                self._busy = True
            try:
                result = task.fn()
            except Exception as exc:
                if task.failed is None:
                    log.exception("rig task failed")
                else:
                    self._send(task.failed, exc)
            else:
                if task.done is not None:
                    self._send(task.done, result)
            finally:
                del task  # keep no finished run (its data) alive while the thread waits
                with self._cond:
                    self._busy = False

    def _send(self, callback: Callable[[Any], None], value: Any) -> None:
        """Hand a result to the GUI thread; dropped if the window is gone (a task stuck in
        an instrument call that returns after the window closed, ADR 0170)."""
        try:
            self._deliver.emit(callback, value)
        except RuntimeError:
            log.warning("a rig task ended after the window closed; its result is dropped")

    def _on_deliver(self, callback: Callable[[Any], None], value: Any) -> None:
        callback(value)
