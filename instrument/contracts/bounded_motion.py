"""Waiting while a bounded motion goes on (ADR 0201).

Every motion gelrig commands ends by itself unless gelrig renews it: a stage move longer than
``[stage] motion_bound`` goes out as absolute segments, a rheometer rotation as time-limited
ones, and every later call to the driver renews a segment that is due. A caller that starts a
motion and then only waits lets time pass with :func:`keep_moving`, which renews the motion
every quarter of the bound and wakes at the same clock time as one ``clock.sleep``.
"""

from __future__ import annotations

from typing import Protocol

from gelrig.instrument.core.clock import Clock

#: Share of the motion bound between two renewals while waiting.
RENEW_SHARE = 0.25


class Renewable(Protocol):
    """An instrument whose motion in progress is renewed by :meth:`keep_alive`."""

    def keep_alive(self) -> None:
        ...


def keep_moving(clock: Clock, axis: Renewable, duration: float, bound: float) -> None:
    """Let ``duration`` s pass on ``clock`` while ``axis`` moves, renewing its motion every
    ``RENEW_SHARE * bound`` s (``bound``: the axis's ``motion_bound``)."""
    end = clock.now() + duration
    period = RENEW_SHARE * bound
    while end - clock.now() > period:
        clock.sleep(period)
        axis.keep_alive()
    clock.sleep_until(end)
