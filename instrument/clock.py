"""The injected clock: everything that waits or timestamps asks a Clock.

A real clock serves the rig; a virtual clock makes a 3000 s hold pass in no wall time (a sleep
advances time at once and simulators compute their state from ``now()``); a paced clock runs
virtual time at k times real time for demos and the GUI.
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
    """

    def __init__(self, rate: float = 1.0, start: float = 0.0):
        self._lock = threading.Lock()
        self._rate = self._check_rate(rate)
        self._anchor_virtual = float(start)
        self._anchor_real = time.monotonic()

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
            self._anchor_virtual = self._now_locked()
            self._anchor_real = time.monotonic()
            self._rate = rate

    def _now_locked(self) -> float:
        if math.isinf(self._rate):
            return self._anchor_virtual
        return self._anchor_virtual + self._rate * (time.monotonic() - self._anchor_real)

    def now(self) -> float:
        with self._lock:
            return self._now_locked()

    def sleep(self, dt: float) -> None:
        if dt > 0:
            self.sleep_until(self.now() + dt)

    def sleep_until(self, deadline: float) -> None:
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


def clock_from_spec(spec: str) -> Clock:
    """Build a clock from ``real``, ``virtual`` or ``paced:K`` (K > 0, or ``inf``)."""
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
            return PacedClock(rate)
    from instrument.errors import ConfigError

    raise ConfigError("clock", spec, "allowed: real, virtual, paced:K with K > 0 (e.g. paced:10)")
