"""``rest``: the plate backed off clear of the sphere, the force recorded for a while (the
sphere recovering between holds, the load cell's baseline)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.core.fields import Field, param
from gelrig.protocols.caps import stage_position_error, stage_speed_error
from gelrig.protocols.rig import CompressionRig
from gelrig.protocols.steps.acquire import COLUMNS, ForceRecorder
from gelrig.protocols.steps.base import Limits, StepDefinition, StepParams, StepPlan, StepResult
from gelrig.protocols.steps.plate import (
    Ctx,
    first_touch_field,
    force_stats,
    home_if_needed,
    known_touch,
    rate_field,
)


@dataclass(frozen=True)
class RestParams(StepParams):
    """Parameters of a rest: how long, how fast to sample, how far clear of the sphere."""

    duration: float = param(Field("duration", "s", 300.0, 0.0, 7 * 86400.0, lo_open=True,
                                  help="time at rest"))
    rate: float = rate_field()
    clear: float = param(Field(
        "clear", "m", 1e-3, 0.0, 20e-3, display="mm",
        help="back the plate off to at least this far before first touch (if it is known)"))
    first_touch: float | None = first_touch_field()


@dataclass(frozen=True)
class RestResult(StepResult):
    """The force at rest: its mean and standard deviation, and its drift (mean of the last
    tenth minus mean of the first tenth); the plate's mean position."""

    duration_s: float
    samples: int
    position_m: float
    force_mean_N: float  # noqa: N815 (run.json key: units in the name)
    force_sd_N: float  # noqa: N815
    force_drift_N: float  # noqa: N815


class Rest(StepDefinition[CompressionRig, RestParams, RestResult]):
    """The plate clear of the sphere, record the force for a while."""

    kind: ClassVar[str] = "rest"
    rig = CompressionRig
    Params, Result = RestParams, RestResult
    description: ClassVar[str] = "rest, plate clear"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: RestParams, limits: Limits) -> StepPlan:
        p = params
        return StepPlan(p.duration, p.clear, [
            f"back off to {p.clear * 1e3:g} mm before first touch if closer, then record "
            f"the force for {p.duration:g} s at {p.rate:g} Hz"], samples=p.duration * p.rate)

    def preflight(self, params: RestParams, rig: CompressionRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        why = [stage_speed_error(rig.limits.fast_speed, rig.stage_caps)]
        if params.first_touch is not None:
            why.append(stage_position_error(max(params.first_touch - params.clear, 0.0),
                                            rig.stage_caps))
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: RestParams) -> RestResult:
        p, rig = params, ctx.rig
        touch = known_touch(ctx, p.first_touch)
        ctx.interlocks = rig.interlocks(overlap=touch is not None)
        home_if_needed(ctx)
        rec = ForceRecorder(ctx, p.rate, first_touch=math.nan if touch is None else touch)
        rec.start()
        if touch is not None and rig.stage.position() > touch - p.clear:
            rig.stage.set_velocity(rig.limits.fast_speed, rig.limits.acceleration)
            rig.stage.move_to(max(touch - p.clear, rig.stage_caps.min_position_m), wait=False)
        rec.until_stopped()  # no samples from before now are kept
        rec.clear()
        held = rec.dwell(p.duration, progress=True, label="rest", endable=True)
        cols = rec.columns()
        return RestResult(held, int(cols["force_N"].size), **force_stats(cols))
