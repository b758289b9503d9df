"""``wait``: hold the stage where it is and record the force for a while, the interlocks
watching every sample (a pause between moves; the sphere relaxing under a fixed plate)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.core.fields import Field, param
from gelrig.protocols.rig import CompressionRig
from gelrig.protocols.steps.acquire import COLUMNS, ForceRecorder
from gelrig.protocols.steps.base import Limits, StepDefinition, StepParams, StepPlan, StepResult
from gelrig.protocols.steps.plate import Ctx, force_stats, known_touch, rate_field


@dataclass(frozen=True)
class WaitParams(StepParams):
    """Parameters of a wait: how long and how fast to sample."""

    duration: float = param(Field("duration", "s", 60.0, 0.0, 7 * 86400.0, lo_open=True,
                                  help="time the stage is held where it is"))
    rate: float = rate_field()


@dataclass(frozen=True)
class WaitResult(StepResult):
    """The force during the wait (mean, standard deviation, drift: last tenth minus first
    tenth), the plate's mean position and its span (max - min: 0 when nothing moved)."""

    duration_s: float
    samples: int
    position_m: float
    position_span_m: float
    force_mean_N: float  # noqa: N815 (run.json key: units in the name)
    force_sd_N: float  # noqa: N815
    force_drift_N: float  # noqa: N815


class Wait(StepDefinition[CompressionRig, WaitParams, WaitResult]):
    """Hold the stage where it is and record the force for a while."""

    kind: ClassVar[str] = "wait"
    rig = CompressionRig
    Params, Result = WaitParams, WaitResult
    description: ClassVar[str] = "wait"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: WaitParams, limits: Limits) -> StepPlan:
        p = params
        return StepPlan(p.duration, 0.0, [
            f"hold the stage where it is, record the force for {p.duration:g} s at "
            f"{p.rate:g} Hz"], samples=p.duration * p.rate)

    def run(self, ctx: Ctx, params: WaitParams) -> WaitResult:
        p, rig = params, ctx.rig
        touch = known_touch(ctx, None)
        ctx.interlocks = rig.interlocks(overlap=touch is not None)
        rec = ForceRecorder(ctx, p.rate, first_touch=math.nan if touch is None else touch)
        rec.start()
        if rig.stage.is_moving():  # nothing of an earlier motion carries into the wait
            rig.stage.stop(immediate=True)
        rec.until_stopped()  # and no samples from before it (read up to now, not kept)
        rec.clear()
        held = rec.dwell(p.duration, progress=True, label="wait", endable=True)
        cols = rec.columns()
        z = cols["position_m"]
        span = float(z.max() - z.min()) if z.size else math.nan
        stats = force_stats(cols)
        return WaitResult(held, int(z.size), stats.pop("position_m"), span, **stats)
