"""Bounded motion segments for the stage (ADR 0201): a long move as absolute targets renewed.

gelrig never sends the stage a motion that would go on for longer than the bound ``T``
(``StageConfig.motion_bound_s``, 2 s) without hearing from gelrig again. A move that would take
longer, and a velocity move (which has no end), is sent as a MOT_MOVE_ABSOLUTE to a target at
most ``L`` ahead of where the stage is, and renewed, with a new target ``L`` ahead of the
position then, every ``T / 4`` while gelrig runs. ``L = v (T - v / a)``: left alone after any
renewal, the stage is at rest within ``T`` (from rest, the trapezoid over ``L`` lasts
``L / v + v / a = T``). A renewal that comes in time finds the stage still cruising (it
would start to slow down only ``T - 1.5 v / a`` after the last one), so the commanded speed
profile of the whole move is the one a single command would give.

Where the speed and acceleration cannot keep both promises (``v / a`` above about ``T / 3``,
far below the Z825B's speeds at the rig's accelerations), the profile wins and the bound
becomes :attr:`SegmentPlan.stop_within` (``T / 2 + 1.5 v / a``), which the driver reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: A segment is renewed after this fraction of the bound.
RENEW_FRACTION = 0.25
#: Least time (fraction of the bound) between a renewal and the moment the stage could start
#: slowing down if no other renewal came: the slack a renewal may be late by.
SLACK_FRACTION = 0.25
_TOLERANCE_S = 1e-9


def rest_to_rest_time(distance: float, speed: float, accel: float) -> float:
    """Time (s) of a trapezoid (or triangle) move over ``distance`` from rest to rest."""
    d = abs(distance)
    if d <= speed * speed / accel:
        return 2.0 * math.sqrt(d / accel)
    return d / speed + speed / accel


@dataclass(frozen=True)
class SegmentPlan:
    """How a move at ``speed`` (m/s) with ``accel`` (m/s^2) is cut for the bound (s)."""

    speed: float
    accel: float
    bound: float
    lookahead: float  # m: a segment's target lies at most this far ahead of the stage
    renew_every: float  # s
    late_after: float  # s: later than this, the stage may already be slowing down
    stop_within: float  # s: left alone after a renewal, the stage is at rest by then

    @classmethod
    def of(cls, speed: float, accel: float, bound: float) -> SegmentPlan:
        if not (speed > 0 and accel > 0 and bound > 0):
            raise ValueError(f"speed, accel and bound must be > 0: {speed}, {accel}, {bound}")
        brake = speed * speed / (2.0 * accel)  # distance to slow down from cruise
        renew = RENEW_FRACTION * bound
        least = speed * (renew + SLACK_FRACTION * bound) + brake
        lookahead = max(speed * (bound - speed / accel), least)
        return cls(speed, accel, bound, lookahead, renew, (lookahead - brake) / speed,
                   max(lookahead / speed + speed / accel, bound))

    def fits(self, distance: float) -> bool:
        """True if a move over ``distance`` from rest ends within the bound: sent whole."""
        return rest_to_rest_time(distance, self.speed, self.accel) <= self.bound + _TOLERANCE_S


@dataclass
class BoundedMove:
    """One segmented move in progress, in the driver's position units.

    ``final`` is where the move ends (a velocity move: the travel limit it heads for),
    ``lookahead`` the plan's look-ahead in the same units, ``target`` the last target sent
    and ``renewed_at`` when (clock time).
    """

    final: float
    direction: int
    lookahead: float
    plan: SegmentPlan
    target: float
    renewed_at: float

    def due(self, now: float) -> bool:
        """True once the segment should be renewed."""
        return now - self.renewed_at >= self.plan.renew_every - _TOLERANCE_S

    def late(self, now: float) -> bool:
        """True if a renewal now comes after the stage may have started to slow down."""
        return now - self.renewed_at > self.plan.late_after + _TOLERANCE_S

    def next_target(self, position: float) -> float:
        """The target of a segment renewed at ``position``: ``lookahead`` ahead, or the final
        target once that is nearer."""
        ahead = position + self.direction * self.lookahead
        return self.final if (self.final - ahead) * self.direction <= 0 else ahead
