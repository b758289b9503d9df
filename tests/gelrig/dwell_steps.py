"""A user step kind for the tests of ``gelrig analyze`` on any run: ``dwells`` ramps into the
sphere and stops at each of several overlaps for a while (relaxation holds inside one step,
not a ramp_hold), then backs off. Written on the plate helpers the built-in kinds use
(gelrig.protocols.steps.plate)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import gelrig
from gelrig.protocols.steps import plate

Limits = gelrig.CompressionLimits | gelrig.ShearLimits


@dataclass(frozen=True)
class DwellsParams(gelrig.StepParams):
    """Overlaps to stop at (m), how long at each, the ramp's speed."""

    first: float = gelrig.param(gelrig.Field("first", "m", 0.4e-3, 0.0, 2e-3, lo_open=True,
                                             display="mm", help="first overlap"))
    second: float = gelrig.param(gelrig.Field("second", "m", 0.8e-3, 0.0, 2e-3, lo_open=True,
                                              display="mm", help="second overlap"))
    dwell: float = gelrig.param(gelrig.Field("dwell", "s", 60.0, 0.0, 3600.0, lo_open=True,
                                             help="time at each overlap"))
    speed: float = gelrig.param(gelrig.Field("speed", "m/s", 37.26e-6, 0.0, 1e-3,
                                             lo_open=True, display="mm/s", help="ramp speed"))


@dataclass(frozen=True)
class DwellsResult(gelrig.StepResult):
    """Where first touch was and how many samples were recorded."""

    first_touch_m: float
    samples: int


@gelrig.register_step
class Dwells(gelrig.StepDefinition[gelrig.CompressionRig, DwellsParams, DwellsResult]):
    """Ramp in, stop at two overlaps in turn, back off."""

    kind = "dwells"
    rig = gelrig.CompressionRig
    Params, Result = DwellsParams, DwellsResult
    description = "stops at two overlaps"
    columns: ClassVar[dict[str, str]] = gelrig.ForceRecorder.columns_published

    def plan(self, params: DwellsParams, limits: Limits) -> gelrig.StepPlan:
        p = params
        return gelrig.StepPlan(2 * p.dwell + p.second / p.speed, 2 * p.second + 4e-3,
                               [f"stop at {p.first * 1e3:g} and {p.second * 1e3:g} mm"],
                               samples=(2 * p.dwell + p.second / p.speed) * 100)

    def preflight(self, params: DwellsParams, rig: gelrig.CompressionRig,
                  earlier: tuple[type[gelrig.StepResult], ...]) -> list[str]:
        return plate.touch_problems("dwells", None, (-0.1e-3, params.second), rig, earlier)

    def run(self, ctx: plate.Ctx, params: DwellsParams) -> DwellsResult:
        p, rig = params, ctx.rig
        touch = plate.needed_touch(ctx, None, "dwells")
        rig.first_touch = touch
        ctx.interlocks = rig.interlocks(overlap=True)
        rec = gelrig.ForceRecorder(ctx, 100.0, first_touch=touch)
        plate.approach(ctx, rec, touch - 0.1e-3, 1.0)
        for depth in (p.first, p.second):
            rig.stage.set_velocity(p.speed, rig.limits.acceleration)
            plate.move_recorded(ctx, rec, touch + depth, "ramp")
            rec.dwell(p.dwell)
        samples = int(rec.columns()["t_s"].size)
        plate.retract(ctx, rec, touch, 2e-3)
        return DwellsResult(touch, samples)
