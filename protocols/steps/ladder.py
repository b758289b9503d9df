"""Sliding-speed ladder (paper): for each overlap, for each speed, sweep clockwise over a set
travel, wait, sweep back, wait. Travel per leg is a distance (the paper's "3000 s" at every
speed cannot be one travel), so the plan states the resulting duration."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

from instrument import paper
from instrument.errors import ConfigError, GelrigError
from instrument.fields import Field
from instrument.sliding import rpm_from_speed
from protocols.context import StepContext
from protocols.interlocks import Interlock
from protocols.rig import ShearLimits, ShearRig
from protocols.steps.arm import COLUMNS, ArmRecorder
from protocols.steps.base import Params, PlanCheck, StepDefinition, StepPlan

_SPEED = Field("speeds", "m/s", None, 0.0, 0.01, lo_open=True)


class SpeedLadder(StepDefinition):
    kind: ClassVar[str] = "speed_ladder"
    rig: ClassVar[str] = "shear"
    description: ClassVar[str] = "sliding-speed ladder"
    columns: ClassVar[dict[str, str]] = COLUMNS
    fields: ClassVar[tuple[Field, ...]] = (
        Field("overlaps", "", 5, 1, 20, integer=True, help="number of overlap levels"),
        Field("first_overlap", "m", 0.38e-3, 0.0, 5e-3, lo_open=True,
              help="shallowest overlap below the touch gap"),
        Field("overlap_step", "m", 0.1e-3, 0.0, 1e-3, help="between overlap levels"),
        Field("travel", "m", 20e-3, 0.0, 0.15, lo_open=True, help="arc travel of one leg"),
        Field("wait", "s", 60.0, 0.0, 86400.0, help="rest after each leg"),
        Field("interval", "s", 0.1, 0.001, 10.0, help="measurement-stream interval"),
        Field("read_period", "s", 2.0, 0.01, 60.0, help="how often the stream is read"),
        Field("touch_gap", "m", math.nan, 0.0, 0.05,
              help="gap at first touch; default: from the contact search"),
        Field("centre_angle", "rad", math.nan, -2 * math.pi, 2 * math.pi,
              help="arm angle over the lower sphere; default: from the contact search"),
    )

    def parse(self, table: Mapping[str, Any], prefix: str, source: str | None) -> Params:
        rest = {k: v for k, v in table.items() if k != "speeds"}
        params = super().parse(rest, prefix, source)
        raw = table.get("speeds", list(paper.SPEEDS))
        if not isinstance(raw, list) or not raw:
            raise ConfigError(f"{prefix}speeds", raw, "a non-empty list of speeds (m/s)", source)
        params["speeds"] = [_SPEED.parse(v, f"{prefix}speeds[{i}].", source)
                            for i, v in enumerate(raw)]
        return params

    def overlaps(self, params: Params) -> list[float]:
        return [params["first_overlap"] + i * params["overlap_step"]
                for i in range(int(params["overlaps"]))]

    def plan(self, params: Params, limits: Any) -> StepPlan:
        overlaps = self.overlaps(params)
        per_overlap = sum(2 * params["travel"] / v + 2 * params["wait"] for v in params["speeds"])
        lines = [
            f"overlaps {', '.join(f'{d * 1e3:.2f}' for d in overlaps)} mm below the touch gap",
            "speeds " + ", ".join(f"{v:.3g} m/s ({rpm_from_speed(v, paper.ARM):.4f} rpm)"
                                  for v in params["speeds"]),
            f"each: {params['travel'] * 1e3:g} mm clockwise, wait {params['wait']:g} s, back, "
            f"wait; {len(overlaps) * len(params['speeds']) * 2} passes",
        ]
        for v in params["speeds"]:
            lines.append(f"  leg at {v:.3g} m/s lasts {params['travel'] / v:,.0f} s")
        checks = []
        if isinstance(limits, ShearLimits):
            ok = max(overlaps) <= limits.max_overlap
            checks.append(PlanCheck("overlap", ok, f"deepest overlap {max(overlaps) * 1e3:.2f} mm "
                                    f"{'<=' if ok else '>'} limit {limits.max_overlap * 1e3:g} mm"))
        travel = len(overlaps) * len(params["speeds"]) * 2 * params["travel"]
        return StepPlan(len(overlaps) * per_overlap, travel, lines, checks)

    def run(self, ctx: StepContext, params: Params) -> dict[str, Any]:
        rig = ctx.rig
        assert isinstance(rig, ShearRig)
        rheo = rig.rheometer
        arm = rheo.config.arm
        touch = params["touch_gap"]
        if math.isnan(touch):
            touch = ctx.result("touch_gap_m")
        centre = params["centre_angle"]
        if math.isnan(centre):
            centre = ctx.result("lower_sphere_angle_rad")
        if touch is None or centre is None or not math.isfinite(touch) \
                or not math.isfinite(centre):
            raise GelrigError("speed_ladder needs touch_gap and centre_angle, or a shear "
                              "contact search before it")
        ctx.interlocks = (
            Interlock("torque", "torque_Nm", rig.limits.max_torque, "N*m"),
            Interlock("normal force", "normal_force_N", rig.limits.max_normal_force, "N"),
        )
        if not rheo.status().gap_referenced:
            rheo.zero_gap()
        rec = ArmRecorder(ctx, params["interval"], params["read_period"])
        half = params["travel"] / 2 / arm
        start, end = centre - half, centre + half
        reposition = min(rheo.config.max_speed, 1e-3)
        overlaps = self.overlaps(params)
        legs = len(overlaps) * len(params["speeds"]) * 2
        plan = self.plan(params, rig.limits)
        t0 = ctx.clock.now()
        done = 0
        passes = []
        try:
            for depth in overlaps:
                ctx.checkpoint()
                rheo.set_gap(touch + 0.5e-3)  # lift clear, go to the start angle, lower
                rec.turn_to(start, reposition)
                rheo.set_gap(touch - depth)
                for speed in params["speeds"]:
                    for direction, target in ((1.0, end), (-1.0, start)):
                        ctx.checkpoint()
                        rec.labels = {"pass": float(done), "direction": direction,
                                      "speed_m_s": speed, "overlap_m": depth}
                        rec.turn_to(target, speed)
                        rec.labels = {**rec.labels, "pass": -1.0}
                        rec.dwell(params["wait"])
                        passes.append({"pass": done, "overlap_m": depth, "speed_m_s": speed,
                                       "direction": direction})
                        done += 1
                        elapsed = ctx.clock.now() - t0
                        ctx.progress(done / legs, elapsed, plan.duration - elapsed,
                                     f"overlap {depth * 1e3:.2f} mm, {speed:.3g} m/s",
                                     overlap_m=depth, speed_m_s=speed)
            rheo.set_gap(touch + 0.5e-3)
        finally:
            rec.close()
        return {"touch_gap_m": touch, "centre_angle_rad": centre, "passes": passes}
