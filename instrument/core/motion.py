"""Stage kinematics: a piecewise constant-acceleration trajectory, a pure function of time
(the simulated KDC101's path, and the driver's reconstruction of it from the commanded moves).

Commands replace the future of the trajectory from the moment they arrive and keep its past,
so ``position_at(t)`` is the same whenever it is asked (for any ``t`` up to the latest
command). Moves follow a trapezoid (or triangle) from the configured acceleration and speed;
reaching a travel end stops the stage dead there, as a limit switch does.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

_EPS = 1e-12


@dataclass(frozen=True)
class Phase:
    """From ``t0`` on: position ``x0 + v0*dt + a*dt**2/2`` (until the next phase starts)."""

    t0: float
    x0: float
    v0: float
    a: float

    def x(self, t: float) -> float:
        dt = t - self.t0
        return self.x0 + self.v0 * dt + 0.5 * self.a * dt * dt

    def v(self, t: float) -> float:
        return self.v0 + self.a * (t - self.t0)


def trapezoid_duration(distance: float, v_max: float, accel: float) -> float:
    """Time of a rest-to-rest move over ``distance`` (trapezoid, or triangle if short)."""
    d = abs(distance)
    if d <= v_max * v_max / accel:
        return 2.0 * math.sqrt(d / accel)
    return d / v_max + v_max / accel


def plan_move(t: float, x: float, v: float, target: float, v_max: float, accel: float
              ) -> list[Phase]:
    """Phases from state (x, v) at t to rest at ``target``; the last phase is at rest."""
    d = target - x
    if abs(d) < _EPS and abs(v) < _EPS:
        return [Phase(t, target, 0.0, 0.0)]
    s = math.copysign(1.0, d) if abs(d) >= _EPS else -math.copysign(1.0, v)
    u0 = v * s  # speed towards the target (negative: moving away)
    if u0 < 0 or u0 * u0 / (2 * accel) > abs(d) + _EPS:
        # Cannot reach the target from here without first coming to rest.
        stop = plan_stop(t, x, v, accel)
        rest = stop[-1]
        return stop[:-1] + plan_move(rest.t0, rest.x0, 0.0, target, v_max, accel)
    dist = abs(d)
    vp = min(v_max, math.sqrt(accel * dist + 0.5 * u0 * u0))
    a1 = accel if vp >= u0 else -accel
    t1 = abs(vp - u0) / accel
    d1 = (vp * vp - u0 * u0) / (2 * a1)
    t3 = vp / accel
    d3 = vp * vp / (2 * accel)
    d2 = max(dist - d1 - d3, 0.0)
    t2 = d2 / vp if vp > 0 else 0.0
    phases = [Phase(t, x, v, s * a1)]
    if t2 > 0:
        phases.append(Phase(t + t1, x + s * d1, s * vp, 0.0))
    phases.append(Phase(t + t1 + t2, x + s * (d1 + d2), s * vp, -s * accel))
    phases.append(Phase(t + t1 + t2 + t3, target, 0.0, 0.0))
    return phases


def plan_velocity(t: float, x: float, v: float, direction: int, v_max: float, accel: float
                  ) -> list[Phase]:
    """Ramp from (x, v) to ``direction * v_max`` and keep going."""
    vt = direction * v_max
    dt = abs(vt - v) / accel
    a = math.copysign(accel, vt - v) if dt > 0 else 0.0
    ramp = Phase(t, x, v, a)
    return [ramp, Phase(t + dt, ramp.x(t + dt), vt, 0.0)]


def plan_stop(t: float, x: float, v: float, accel: float, immediate: bool = False
              ) -> list[Phase]:
    """Stop: at once (``immediate``) or along the deceleration ramp."""
    if immediate or abs(v) < _EPS:
        return [Phase(t, x, 0.0, 0.0)]
    dt = abs(v) / accel
    ramp = Phase(t, x, v, -math.copysign(accel, v))
    return [ramp, Phase(t + dt, ramp.x(t + dt), 0.0, 0.0)]


def _first_crossing(p: Phase, duration: float, bound: float, outward: float) -> float | None:
    """Earliest dt in [0, duration] where phase ``p`` passes ``bound`` moving ``outward``."""
    c = p.x0 - bound
    roots: list[float] = []
    if abs(p.a) < _EPS:
        if abs(p.v0) > _EPS:
            roots.append(-c / p.v0)
    else:
        disc = p.v0 * p.v0 - 2.0 * p.a * c
        if disc >= 0:
            r = math.sqrt(disc)
            roots += [(-p.v0 - r) / p.a, (-p.v0 + r) / p.a]
    hits = [
        dt for dt in roots
        if -_EPS <= dt <= duration + _EPS and (p.v0 + p.a * max(dt, 0.0)) * outward > _EPS
    ]
    return max(min(hits), 0.0) if hits else None


def clip_to_travel(phases: list[Phase], lo: float, hi: float, slack: float = 1e-9
                   ) -> tuple[list[Phase], float | None]:
    """Cut ``phases`` where they leave [lo - slack, hi + slack]: a dead stop at the bound.

    Returns the phases and the time of the hit (None if the path stays inside). The slack
    (far below one encoder count) lets a move that ends exactly on a bound end normally.
    """
    for i, p in enumerate(phases):
        duration = phases[i + 1].t0 - p.t0 if i + 1 < len(phases) else math.inf
        hits = [
            (dt, bound)
            for bound, outward in ((lo, -1.0), (hi, 1.0))
            if (dt := _first_crossing(p, duration, bound + outward * slack, outward)) is not None
        ]
        if hits:
            dt, bound = min(hits)
            t_hit = p.t0 + dt
            kept = phases[:i] + ([p] if dt > 0 else [])
            stop_at = bound if dt > 0 else p.x0
            return [*kept, Phase(t_hit, stop_at, 0.0, 0.0)], t_hit
    return phases, None


#: Seconds of past path a trajectory keeps (a day): far more than any acquisition buffer
#: looks back, so a simulator that runs for weeks keeps a bounded path.
HISTORY = 86400.0


class Trajectory:
    """The stage's path through time: the past day's phases are kept, the future is
    replaceable."""

    def __init__(self, x0: float, t0: float = 0.0):
        self._phases = [Phase(t0, x0, 0.0, 0.0)]
        self._starts = [t0]
        self._table: NDArray[np.float64] | None = None  # (t0, x0, v0, a) rows, built lazily

    def _phase(self, t: float) -> Phase:
        i = bisect.bisect_right(self._starts, t) - 1
        return self._phases[max(i, 0)]

    def position_at(self, t: float) -> float:
        """Position in metres at time ``t`` (a pure function of ``t`` up to the last command)."""
        return self._phase(t).x(t)

    def velocity_at(self, t: float) -> float:
        """Velocity in m/s at time ``t``."""
        return self._phase(t).v(t)

    def positions_at(self, ts: NDArray[np.float64]) -> NDArray[np.float64]:
        """``position_at`` for an array of times (one call for a whole acquisition block)."""
        ts = np.asarray(ts, dtype=float)
        if self._table is None:
            self._table = np.array([(p.t0, p.x0, p.v0, p.a) for p in self._phases], dtype=float)
        table = self._table
        idx = np.clip(np.searchsorted(table[:, 0], ts, side="right") - 1, 0, None)
        if idx.size and idx.min() == idx.max():  # one phase (most blocks): no gathers
            t0, x0, v0, a = table[idx[0]]
        else:
            t0, x0, v0, a = (table[idx, k] for k in range(4))
        dt = ts - t0
        out: NDArray[np.float64] = x0 + v0 * dt + 0.5 * a * dt * dt
        return out

    def replace_from(self, t: float, phases: list[Phase]) -> None:
        """Keep the path before ``t`` and follow ``phases`` (starting at ``t``) after it."""
        keep = bisect.bisect_left(self._starts, t)
        # the phase in force HISTORY before t stays, with everything after it
        first = max(bisect.bisect_right(self._starts, t - HISTORY) - 1, 0)
        self._phases = self._phases[min(first, keep):keep] + phases
        self._starts = [p.t0 for p in self._phases]
        self._table = None

    def copy(self) -> Trajectory:
        """A trajectory with the same path (later commands to either leave the other alone)."""
        out = Trajectory.__new__(Trajectory)
        out._phases = list(self._phases)
        out._starts = list(self._starts)
        out._table = None
        return out

    @property
    def end_time(self) -> float:
        """When the final phase starts (for a move: the moment it comes to rest)."""
        return self._phases[-1].t0

    @property
    def final_velocity(self) -> float:
        return self._phases[-1].v0
