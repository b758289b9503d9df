"""The run's watchdog: a run that records no data for too long is faulted.

It watches wall time, not the run's clock: a frozen instrument stops a virtual or paced clock
as surely as the data (the reading thread waits, so simulated time does not advance), while
wall time goes on. Anything the runner publishes counts as a sign of life (samples, progress,
a step starting); a pause disarms it until the run resumes. On expiry it asks the run to end
as a fault (:meth:`RunControl.fail`); if the run's thread is stuck inside an instrument call it
cannot see that, and the owner of the run (the CLI) ends it (see protocols/host.py). Its line
says what the run's thread was doing when it expired, from the thread's current frame:
``stuck in an instrument call (usb6001/sensor.py:310 in read)``, or ``the script's own code
(creep.py:27) has not returned`` (a step kind of the user's in a loop of its own).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from gelrig.protocols.control import RunControl
from gelrig.protocols.events import Event, RunState, StateChanged
from gelrig.protocols.origin import stuck_words, thread_site

log = logging.getLogger(__name__)

KIND = "WatchdogExpired"


class Watchdog:
    """Subscriber + thread: ``control.fail`` after ``timeout`` s (wall) without an event;
    ``thread`` is the run's (what it was doing goes into the message)."""

    def __init__(self, control: RunControl, timeout: float,
                 wall: Callable[[], float] = time.monotonic,
                 thread: threading.Thread | None = None):
        self.control = control
        self.timeout = timeout
        self.wall = wall
        self.thread = thread
        self.expired = False
        self._last = wall()
        self._paused = False
        #: False between the steps of a run (a script computing what to do next is not a
        #: frozen instrument); the clock restarts when it is set again
        self._active = True
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __call__(self, event: Event) -> None:
        self._last = self.wall()
        if isinstance(event, StateChanged):
            self._paused = event.new is RunState.PAUSED

    @property
    def active(self) -> bool:
        return self._active

    @active.setter
    def active(self, value: bool) -> None:
        self._last = self.wall()
        self._active = value

    def start(self) -> Watchdog:
        """Arm it (no-op when ``timeout`` is 0); returns self."""
        if self.timeout > 0 and self._thread is None:
            self._last = self.wall()
            self._thread = threading.Thread(target=self._watch, name="run watchdog",
                                            daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()

    def check(self) -> bool:
        """Fault the run if it has been silent too long; True if it did (now or before)."""
        if self.expired or self._paused or not self._active or self.control.abort_requested:
            return self.expired
        silent = self.wall() - self._last
        if silent > self.timeout:
            self.expired = True
            shown = f"{silent:.1f}" if silent < 10 else f"{silent:.0f}"
            message = (f"watchdog: no data for {shown} s (limit {self.timeout:g} s); "
                       f"{stuck_words(*thread_site(self.thread))}")
            log.error("%s", message)
            self.control.fail(KIND, message)
        return self.expired

    def _watch(self) -> None:
        period = min(1.0, self.timeout / 10)
        while not self._stop.wait(period):
            if self.check():
                return
