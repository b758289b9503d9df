"""``move``: the plate to an absolute position (``to``) or by a distance (``by``) at a speed,
the force recorded all the way and the interlocks watching every sample."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.core.fields import Field, Where, param
from gelrig.protocols.caps import stage_position_error, stage_speed_error
from gelrig.protocols.rig import CompressionRig
from gelrig.protocols.steps.acquire import COLUMNS, ForceRecorder
from gelrig.protocols.steps.base import Limits, StepDefinition, StepParams, StepPlan, StepResult
from gelrig.protocols.steps.plate import Ctx, home_if_needed, known_touch, move_recorded, rate_field

#: Longest travel a move may ask for (m): the Z825B's.
TRAVEL = 25e-3


@dataclass(frozen=True)
class MoveParams(StepParams):
    """Parameters of a move: where to (``to`` or ``by``, exactly one) and how fast."""

    speed: float = param(Field("speed", "m/s", None, 0.0, 2.6e-3, lo_open=True, display="mm/s",
                               help="plate speed (at most [stage] max_velocity)"))
    to: float | None = param(Field("to", "m", None, 0.0, TRAVEL, optional=True, display="mm",
                                   help="stage position to go to (absolute)"))
    by: float | None = param(Field("by", "m", None, -TRAVEL, TRAVEL, optional=True,
                                   display="mm",
                                   help="distance to go (relative; + toward the sphere)"))
    rate: float = rate_field()

    def validate(self, where: Where) -> None:
        if (self.to is None) == (self.by is None):
            raise where.error("to", "both" if self.to is not None else "missing",
                              "give exactly one of to (absolute) and by (relative)")


@dataclass(frozen=True)
class MoveResult(StepResult):
    """Where the plate started and ended, where it was sent, how long it took, and the force
    on the way (its largest value and the mean of the last 0.1 s)."""

    start_position_m: float
    end_position_m: float
    target_m: float
    speed_m_s: float
    duration_s: float
    samples: int
    force_max_N: float  # noqa: N815 (run.json key: units in the name)
    force_end_N: float  # noqa: N815


class Move(StepDefinition[CompressionRig, MoveParams, MoveResult]):
    """Move the plate to a position or by a distance, recording the force."""

    kind: ClassVar[str] = "move"
    rig = CompressionRig
    Params, Result = MoveParams, MoveResult
    description: ClassVar[str] = "move the plate"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: MoveParams, limits: Limits) -> StepPlan:
        p = params
        where = (f"to {p.to * 1e3:g} mm" if p.to is not None
                 else f"by {p.by * 1e3:+g} mm" if p.by is not None else "")
        travel = abs(p.by) if p.by is not None else 0.0  # an absolute move: not known before
        return StepPlan(travel / p.speed, travel, [
            f"move the plate {where} at {p.speed * 1e3:g} mm/s, recording the force at "
            f"{p.rate:g} Hz"], samples=travel / p.speed * p.rate)

    def preflight(self, params: MoveParams, rig: CompressionRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        p, caps = params, rig.stage_caps
        why = [stage_speed_error(p.speed, caps)]
        if p.to is not None:
            why.append(stage_position_error(p.to, caps))
        elif p.by is not None and abs(p.by) > caps.max_position_m - caps.min_position_m:
            why.append(f"by {p.by * 1e3:+g} mm is more than the stage's travel "
                       f"[{caps.min_position_m * 1e3:g}, {caps.max_position_m * 1e3:g}] mm")
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: MoveParams) -> MoveResult:
        p, rig = params, ctx.rig
        touch = known_touch(ctx, None)
        ctx.interlocks = rig.interlocks(overlap=touch is not None)
        home_if_needed(ctx)
        rec = ForceRecorder(ctx, p.rate, first_touch=math.nan if touch is None else touch,
                            block_time=min(0.5, max(0.1, 2e-6 / p.speed)))
        rec.start()
        start, t0 = rig.stage.position(), ctx.clock.now()
        target = p.to if p.to is not None else start + (p.by or 0.0)
        rig.stage.set_velocity(p.speed, rig.limits.acceleration)
        move_recorded(ctx, rec, target, "move")
        cols = rec.columns()
        force = cols["force_N"]
        last = force[-max(1, round(0.1 * p.rate)):]
        return MoveResult(start, rig.stage.position(), target, p.speed, ctx.clock.now() - t0,
                          int(force.size), float(force.max()) if force.size else math.nan,
                          float(last.mean()) if last.size else math.nan)
