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
from dataclasses import dataclass, field
from typing import Any

from PySide6.QtCore import QObject

from gelrig.gui import offthread

log = logging.getLogger(__name__)

Done = Callable[[Any], None]
Failed = Callable[[BaseException], None]


@dataclass
class _Task:
    fn: Callable[[], Any]
    token: int


@dataclass
class _Queue:
    """What the GUI thread and the worker share: plain Python, no Qt object (ADR 0395)."""

    cond: threading.Condition = field(default_factory=threading.Condition)
    tasks: deque[_Task] = field(default_factory=deque)
    finished: list[_Task] = field(default_factory=list)  # let go of on the GUI thread
    busy: bool = False
    closing: bool = False


def _serve(queue: _Queue) -> None:
    """The worker: run each task, then hand the task and its result to the GUI thread
    before telling it, so the last reference to anything a task holds (a window its
    closure names) is always dropped on the GUI thread, never here."""
    while True:
        with queue.cond:
            while not queue.tasks and not queue.closing:
                queue.cond.wait()
            if not queue.tasks:
                return
            task = queue.tasks.popleft()
            queue.busy = True
        token = task.token
        box: list[object] = []
        try:
            box.append((True, task.fn()))
        except Exception as exc:
            box.append((False, exc))
        with queue.cond:
            queue.finished.append(task)
        del task
        offthread.send(token, box)
        with queue.cond:
            queue.busy = False


class RigThread(QObject):
    """A single worker thread with a FIFO queue (urgent tasks first), callbacks on the GUI
    thread."""

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        offthread.ready()  # the relay is made here, on the GUI thread
        self._queue = _Queue()
        self._thread = threading.Thread(target=_serve, args=(self._queue,),
                                        name="gelrig-rig", daemon=True)
        self._thread.start()

    def submit(self, fn: Callable[[], Any], done: Done | None = None,
               failed: Failed | None = None, urgent: bool = False) -> bool:
        """Queue ``fn``; False if the thread is shutting down. ``done``/``failed`` run on
        the GUI thread, unless this object has been deleted by then (a task stuck in an
        instrument call that returns after the window closed, ADR 0170)."""
        queue = self._queue
        with queue.cond:
            if queue.closing:
                return False
        token = offthread.expect(lambda value: self._arrived(value, done, failed), owner=self)
        task = _Task(fn, token)
        with queue.cond:
            if urgent:
                queue.tasks.appendleft(task)
            else:
                queue.tasks.append(task)
            queue.cond.notify()
        return True

    @property
    def idle(self) -> bool:
        queue = self._queue
        with queue.cond:
            return not queue.busy and not queue.tasks

    def shutdown(self, timeout: float = 30.0) -> bool:
        """Run what is queued, then end the thread; True if it ended within ``timeout``."""
        with self._queue.cond:
            self._queue.closing = True
            self._queue.cond.notify()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _arrived(self, value: object, done: Done | None, failed: Failed | None) -> None:
        with self._queue.cond:  # the finished tasks are let go of here, on the GUI thread
            finished, self._queue.finished = self._queue.finished, []
        del finished
        assert isinstance(value, tuple)
        ok, result = value
        if ok:
            if done is not None:
                done(result)
        elif failed is None:
            log.error("rig task failed", exc_info=result)
        else:
            failed(result)
