"""``shear_wait``: the shear rig's ``wait``: hold the arm and the gap where they are and
record the rheometer's stream for a while, the interlocks (torque, normal force) watching
every point."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.core.fields import Field, param
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import ShearRig
from gelrig.protocols.steps.arm import COLUMNS, ArmRecorder
from gelrig.protocols.steps.base import Limits, StepDefinition, StepParams, StepPlan, StepResult


@dataclass(frozen=True)
class ShearWaitParams(StepParams):
    """Parameters of a wait on the shear rig: how long and the stream's interval."""

    duration: float = param(Field("duration", "s", 60.0, 0.0, 7 * 86400.0, lo_open=True,
                                  help="time the arm and the gap are held where they are"))
    interval: float = param(Field("interval", "s", 0.05, 0.001, 10.0,
                                  help="measurement-stream interval"))


@dataclass(frozen=True)
class ShearWaitResult(StepResult):
    """The torque and normal force during the wait (means, and the torque's standard
    deviation), where the arm was (its angle's span: 0 when nothing turned) and the gap."""

    duration_s: float
    samples: int
    angle_span_rad: float
    gap_m: float
    torque_mean_Nm: float  # noqa: N815 (run.json key: units in the name)
    torque_sd_Nm: float  # noqa: N815
    normal_force_mean_N: float  # noqa: N815


class ShearWait(StepDefinition[ShearRig, ShearWaitParams, ShearWaitResult]):
    """Hold the arm and the gap where they are and record the stream for a while."""

    kind: ClassVar[str] = "shear_wait"
    rig = ShearRig
    Params, Result = ShearWaitParams, ShearWaitResult
    description: ClassVar[str] = "wait"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: ShearWaitParams, limits: Limits) -> StepPlan:
        p = params
        return StepPlan(p.duration, 0.0, [
            f"hold the arm and the gap, record the stream for {p.duration:g} s every "
            f"{p.interval * 1e3:g} ms"], samples=p.duration / p.interval)

    def run(self, ctx: StepContext[ShearRig], params: ShearWaitParams) -> ShearWaitResult:
        p, rig = params, ctx.rig
        ctx.interlocks = rig.interlocks()
        rig.hold()  # the arm stays where it is
        rec = ArmRecorder(ctx, p.interval, read_period=max(p.interval, 0.5))
        try:
            rec.settle()  # an earlier motion ends before the record starts
            rec.keep = True
            start = ctx.clock.now()
            rec.dwell(p.duration)
            held = ctx.clock.now() - start
        finally:
            rec.close()
        cols = rec.columns()
        n = int(cols["t_s"].size)
        angle, torque = cols["angle_rad"], cols["torque_Nm"]

        def mean(key: str) -> float:
            return float(cols[key].mean()) if n else math.nan

        return ShearWaitResult(held, n, float(angle.max() - angle.min()) if n else math.nan,
                               mean("gap_m"), mean("torque_Nm"),
                               float(torque.std()) if n else math.nan,
                               mean("normal_force_N"))
