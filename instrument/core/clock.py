"""The injected clock: everything that waits or timestamps asks a Clock.

A real clock serves the rig; a virtual clock makes a 3000 s hold pass in no wall time (a sleep
advances time at once and simulators compute their state from ``now()``); a paced clock runs
virtual time at k times real time for demos and the GUI. A run's paced clock
(``clock_from_spec("paced:K")``) scales only the waits: the host's work and its messages to
the twins take their real time, as on the rig, not k times longer (ADR 0240).
"""

from __future__ import annotations

import math
import threading
import time
from typing import Protocol, runtime_checkable


@runtime_checkable
class Clock(Protocol):
    """Time in seconds, monotonic; what waits and timestamps use."""

    def now(self) -> float:
        """Current time in seconds (monotonic, arbitrary origin)."""
        ...

    def sleep(self, dt: float) -> None:
        """Wait ``dt`` seconds (no-op for ``dt <= 0``)."""
        ...

    def sleep_until(self, deadline: float) -> None:
        """Wait until ``now() >= deadline`` (returns at once if already past)."""
        ...


class RealClock:
    """Wall time from ``time.monotonic``; sleeps really sleep."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, dt: float) -> None:
        if dt > 0:
            time.sleep(dt)

    def sleep_until(self, deadline: float) -> None:
        self.sleep(deadline - time.monotonic())


class VirtualClock:
    """Simulated time: a sleep advances time instantly. Monotonic and thread-safe."""

    def __init__(self, start: float = 0.0):
        self._t = float(start)
        self._lock = threading.Lock()

    def now(self) -> float:
        with self._lock:
            return self._t

    def sleep(self, dt: float) -> None:
        if dt > 0:
            with self._lock:
                self._t += dt

    def sleep_until(self, deadline: float) -> None:
        with self._lock:
            if deadline > self._t:
                self._t = float(deadline)

    def advance(self, dt: float) -> None:
        """Move time forward by ``dt`` (>= 0); the same as ``sleep``."""
        if dt < 0:
            raise ValueError(f"a virtual clock cannot go backwards (dt = {dt} s)")
        self.sleep(dt)


class PacedClock:
    """Virtual time running ``rate`` times faster than real time.

    ``rate`` may be changed while running (the GUI's pace control); ``math.inf`` means as fast
    as possible, where a sleep advances time at once as on a :class:`VirtualClock`.

    ``waits_only`` (a run's clock, ADR 0240): time runs ``rate`` times faster than real time
    only while a thread waits on this clock, never past the earliest waiter's deadline, and
    at real time otherwise. The host's work (a block converted, a message framed, a gRPC call
    in transit) then lasts in lab time what it lasts on the rig, instead of ``rate`` times
    longer: a paced twin sees the latencies of the real rig, not those of a computer ``rate``
    times slower. Without it (served simulators shared across processes) time runs at
    ``rate`` times real time throughout.
    """

    def __init__(self, rate: float = 1.0, start: float = 0.0, *, waits_only: bool = False):
        self._lock = threading.Lock()
        self._rate = self._check_rate(rate)
        self._anchor_virtual = float(start)
        self._anchor_real = time.monotonic()
        self.waits_only = waits_only
        self._waiting: list[float] = []  # deadlines of the threads waiting (waits_only)

    @staticmethod
    def _check_rate(rate: float) -> float:
        if not rate > 0:
            raise ValueError(f"pace rate must be > 0 (or inf), got {rate}")
        return float(rate)

    @property
    def rate(self) -> float:
        return self._rate

    def set_rate(self, rate: float) -> None:
        """Change the pace without a jump in ``now()``."""
        rate = self._check_rate(rate)
        with self._lock:
            self._reanchor()
            self._rate = rate

    def _reanchor(self) -> None:
        self._anchor_virtual = self._now_locked()
        self._anchor_real = time.monotonic()

    def _now_locked(self) -> float:
        if math.isinf(self._rate):
            return self._anchor_virtual
        if not self.waits_only:
            return self._anchor_virtual + self._rate * (time.monotonic() - self._anchor_real)
        speed = self._rate if self._waiting else 1.0
        t = self._anchor_virtual + speed * (time.monotonic() - self._anchor_real)
        if self._waiting:  # never past the earliest deadline, never back before the anchor
            t = max(min(t, min(self._waiting)), self._anchor_virtual)
        return t

    def now(self) -> float:
        with self._lock:
            return self._now_locked()

    def sleep(self, dt: float) -> None:
        if dt > 0:
            self.sleep_until(self.now() + dt)

    def sleep_until(self, deadline: float) -> None:
        with self._lock:
            if self._now_locked() >= deadline:
                return
            if math.isinf(self._rate):
                self._anchor_virtual = float(deadline)
                return
            if self.waits_only:  # time runs at the pace from now on, up to the deadline
                self._reanchor()
                self._waiting.append(deadline)
        try:
            while True:
                with self._lock:
                    now = self._now_locked()
                    if now >= deadline:
                        return
                    if math.isinf(self._rate):
                        self._anchor_virtual = float(deadline)
                        return
                    wait = (deadline - now) / self._rate
                # Sleep in slices so a change of rate takes effect promptly.
                time.sleep(min(wait, 0.05))
        finally:
            if self.waits_only:
                with self._lock:
                    self._reanchor()
                    self._waiting.remove(deadline)


def skip_to(clock: Clock, t: float) -> None:
    """Move a virtual or paced clock on to lab time ``t`` at once, if it is not there yet: a
    resumed run continues its run's time base instead of starting again at 0. A real clock's
    time goes on by itself."""
    if isinstance(clock, VirtualClock):
        clock.sleep_until(t)
    elif isinstance(clock, PacedClock):
        with clock._lock:
            if t > clock._now_locked():
                clock._anchor_virtual = float(t)
                clock._anchor_real = time.monotonic()


def clock_from_spec(spec: str, *, waits_only: bool = True) -> Clock:
    """Build a clock from ``real``, ``virtual`` or ``paced:K`` (K > 0, or ``inf``).

    A paced clock scales only the waits unless ``waits_only`` is False (a served simulator,
    whose clients keep their own clock in another process)."""
    spec = spec.strip().lower()
    if spec == "real":
        return RealClock()
    if spec == "virtual":
        return VirtualClock()
    if spec.startswith("paced:"):
        try:
            rate = float(spec.split(":", 1)[1])
        except ValueError:
            rate = -1.0
        if rate > 0:
            return PacedClock(rate, waits_only=waits_only)
    from gelrig.instrument.core.errors import ConfigError

    raise ConfigError("clock", spec, "allowed: real, virtual, paced:K with K > 0 (e.g. paced:10)")
