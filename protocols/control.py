"""Run control shared between the runner thread and whoever commands it (CLI, GUI, tests)."""

from __future__ import annotations

import threading
import time


class Aborted(Exception):
    """Raised inside a step when an abort was requested; the runner stops motion first."""


class RunControl:
    """Pause/resume/abort requests, thread-safe.

    A pause takes effect at the next checkpoint (a point where nothing moves); an abort
    takes effect at once, at the next sample block. A hold (the sample held at a strain while
    it relaxes) cannot pause without changing the physics, but it can be ended early: its
    data is kept and the run goes on with the next phase (:meth:`end_hold`).
    """

    def __init__(self) -> None:
        self._abort = threading.Event()
        self._pause = threading.Event()
        self._resume = threading.Event()
        self._resume.set()
        self.abort_reason = ""
        #: the abort is a fault (a watchdog), not a person's request: the run ends "failed"
        self.fault_kind = ""
        #: wall time (time.monotonic) of the first abort request, or None
        self.abort_time: float | None = None
        self._holding = threading.Event()
        self._end_hold = threading.Event()

    def pause(self) -> None:
        self._pause.set()
        self._resume.clear()

    def resume(self) -> None:
        self._pause.clear()
        self._resume.set()

    def abort(self, reason: str = "abort requested") -> None:
        if not self._abort.is_set():
            self.abort_reason = reason
            self.abort_time = time.monotonic()
        self._abort.set()
        self._resume.set()

    def fail(self, kind: str, reason: str) -> None:
        """End the run as a fault of ``kind`` (e.g. the watchdog's), at the next block."""
        if not self._abort.is_set():
            self.fault_kind = kind
        self.abort(reason)

    def end_hold(self) -> bool:
        """End the hold in progress now (its data is kept; the run goes on); False if no hold
        is in progress (it may just have ended)."""
        if not self._holding.is_set():
            return False
        self._end_hold.set()
        return True

    @property
    def holding(self) -> bool:
        """A step is in a hold that :meth:`end_hold` can end."""
        return self._holding.is_set()

    @property
    def hold_end_requested(self) -> bool:
        return self._end_hold.is_set()

    def enter_hold(self) -> None:
        """A step begins a hold (an older end request does not carry over)."""
        self._end_hold.clear()
        self._holding.set()

    def leave_hold(self) -> None:
        self._holding.clear()
        self._end_hold.clear()

    @property
    def pause_requested(self) -> bool:
        return self._pause.is_set()

    @property
    def abort_requested(self) -> bool:
        return self._abort.is_set()

    def raise_if_aborted(self) -> None:
        if self._abort.is_set():
            raise Aborted(self.abort_reason)

    def wait_resumed(self, poll: float = 0.05) -> None:
        """Block in real time until resumed or aborted (a paused run waits for a person)."""
        while not self._resume.wait(poll):
            pass
        self.raise_if_aborted()
