"""Sliding-speed ladder (paper): for each overlap, for each speed, sweep clockwise over a set
travel, wait, sweep back, wait. Travel per leg is a distance (the paper's "3000 s" at every
speed cannot be one travel), so the plan states the resulting duration."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from gelrig.instrument.core.errors import GelrigError, LimitError
from gelrig.instrument.core.fields import Field, FieldList, Where, param
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.sliding import rpm_from_speed
from gelrig.protocols.bounds import MAX_LADDER_SPEEDS
from gelrig.protocols.caps import arm_speed_error
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import ShearLimits, ShearRig
from gelrig.protocols.steps.arm import COLUMNS, ArmRecorder
from gelrig.protocols.steps.base import (
    Limits,
    PlanCheck,
    StepDefinition,
    StepParams,
    StepPlan,
    StepResult,
    brief,
    given,
    mm,
)
from gelrig.protocols.steps.shear_search import ShearSearchResult

#: Most stream points one read may have to collect: half the MCR 501's stream buffer as the
#: simulator models it (4096 points, UNVERIFIED: docs/decisions/0110), so points are never lost.
STREAM_POINTS_PER_READ = 2048

_SPEED = Field("speeds", "m/s", None, 0.0, 0.01, lo_open=True, display="mm/s")


@dataclass(frozen=True)
class LadderParams(StepParams):
    """Parameters of the sliding-speed ladder (paper: 5 overlaps 0.1 mm apart from 0.38 mm,
    4 speeds)."""

    overlaps: float = param(Field("overlaps", "", 5, 1, 20, integer=True,
                                  help="number of overlap levels"))
    first_overlap: float = param(Field("first_overlap", "m", 0.38e-3, 0.0, 5e-3, lo_open=True,
                                       display="mm",
                                       help="shallowest overlap below the touch gap"))
    overlap_step: float = param(Field("overlap_step", "m", paper.OVERLAP_STEP, 0.0, 1e-3,
                                      display="mm",
                                      help="between overlap levels"))
    speeds: tuple[float, ...] = param(FieldList("speeds", _SPEED, tuple(paper.SPEEDS),
                                             help="sliding speeds, in this order",
                                             max_items=MAX_LADDER_SPEEDS))
    travel: float = param(Field("travel", "m", 20e-3, 0.0, 0.15, lo_open=True, display="mm",
                                help="arc travel of one leg"))
    wait: float = param(Field("wait", "s", 60.0, 0.0, 86400.0, help="rest after each leg"))
    interval: float = param(Field("interval", "s", 0.1, 0.001, 10.0,
                                  help="measurement-stream interval"))
    read_period: float = param(Field("read_period", "s", 2.0, 0.01, 60.0,
                                     help="how often the stream is read"))
    touch_gap: float | None = param(Field("touch_gap", "m", None, 0.0, 0.05, optional=True,
                                          display="mm", help="gap at first touch; default: "
                                                             "from the contact search"))
    centre_angle: float | None = param(Field(
        "centre_angle", "rad", None, -2 * math.pi, 2 * math.pi, optional=True,
        help="arm angle over the lower sphere; default: from the contact search"))

    def validate(self, where: Where) -> None:
        points = self.read_period / self.interval
        if points > STREAM_POINTS_PER_READ:
            raise where.error("read_period", self.read_period,
                              f"at most {STREAM_POINTS_PER_READ} stream intervals "
                              f"({STREAM_POINTS_PER_READ * self.interval:g} s at interval "
                              f"{self.interval:g} s), so the instrument's stream buffer never "
                              "overflows between reads")

    @property
    def levels(self) -> list[float]:
        """The overlaps (m below the touch gap), shallowest first."""
        return [self.first_overlap + i * self.overlap_step for i in range(int(self.overlaps))]


@dataclass(frozen=True, repr=False)
class LadderResult(StepResult):
    """Where the ladder ran, and one row per pass (overlap, speed, direction)."""

    touch_gap_m: float
    centre_angle_rad: float
    passes: list[dict[str, float]] = field(default_factory=list)

    def __repr__(self) -> str:
        n = len(self.passes)
        return brief("LadderResult", f"{n} pass{'' if n == 1 else 'es'} at touch gap "
                     f"{mm(self.touch_gap_m)}", f"centre "
                     f"{math.degrees(self.centre_angle_rad):.2f} deg")


class SpeedLadder(StepDefinition[ShearRig, LadderParams, LadderResult]):
    """For each overlap, for each speed: sweep clockwise, wait, sweep back, wait."""

    kind: ClassVar[str] = "speed_ladder"
    rig = ShearRig
    Params = LadderParams
    Result = LadderResult
    description: ClassVar[str] = "sliding-speed ladder"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: LadderParams, limits: Limits) -> StepPlan:
        p = params
        overlaps = p.levels
        per_overlap = sum(2 * p.travel / v + 2 * p.wait for v in p.speeds)
        lines = [
            f"overlaps {', '.join(f'{d * 1e3:.2f}' for d in overlaps)} mm below the touch gap",
            "speeds " + ", ".join(f"{v:.3g} m/s ({rpm_from_speed(v, paper.ARM):.4f} rpm)"
                                  for v in p.speeds),
            f"each: {p.travel * 1e3:g} mm clockwise, wait {p.wait:g} s, back, "
            f"wait; {len(overlaps) * len(p.speeds) * 2} passes",
        ]
        for v in p.speeds:
            lines.append(f"  leg at {v:.3g} m/s lasts {p.travel / v:,.0f} s")
        checks = []
        if isinstance(limits, ShearLimits):
            ok = max(overlaps) <= limits.max_overlap
            checks.append(PlanCheck("overlap", ok, f"deepest overlap {max(overlaps) * 1e3:.2f} mm "
                                    f"{'<=' if ok else '>'} limit {limits.max_overlap * 1e3:g} mm"))
        travel = len(overlaps) * len(p.speeds) * 2 * p.travel
        duration = len(overlaps) * per_overlap
        return StepPlan(duration, travel, lines, checks, samples=duration / p.interval)

    def preflight(self, params: LadderParams, rig: ShearRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        p, config = params, rig.rheometer.config
        why = [arm_speed_error(v, config) for v in p.speeds]
        cap = min(rig.limits.max_overlap, config.overlap_limit)
        deepest = max(p.levels)
        if deepest > cap:
            why.append(f"overlap {deepest * 1e3:.4g} mm beyond the overlap limit {cap * 1e3:g} mm"
                       " ([limits] max_overlap, [rheometer] overlap_limit)")
        if p.touch_gap is not None:
            why += [rig.gap_error(p.touch_gap - d) for d in p.levels]
        searched = any(issubclass(kind, ShearSearchResult) for kind in earlier)
        if (p.touch_gap is None or p.centre_angle is None) and not searched:
            why.append("speed_ladder needs touch_gap and centre_angle, or a shear contact "
                       "search before it")
        return list(dict.fromkeys(w for w in why if w is not None))

    def run(self, ctx: StepContext[ShearRig], params: LadderParams) -> LadderResult:
        p = params
        rig = ctx.rig
        rheo = rig.rheometer
        arm = rheo.config.arm
        search = ctx.earlier(ShearSearchResult)
        touch = p.touch_gap if p.touch_gap is not None else given(
            search.touch_gap_m if search else None)
        centre = p.centre_angle if p.centre_angle is not None else given(
            search.lower_sphere_angle_rad if search else None)
        if touch is None or centre is None:
            raise GelrigError("speed_ladder needs touch_gap and centre_angle, or a shear "
                              "contact search before it")
        rig.know_touch_gap(touch)
        for why in (rig.gap_error(touch - depth) for depth in p.levels):
            if why is not None:  # refused before anything moves in this step
                raise LimitError(f"{why}; nothing moved")
        ctx.interlocks = rig.interlocks()
        if not rheo.status().gap_referenced:
            rheo.zero_gap()
        rec = ArmRecorder(ctx, p.interval, p.read_period)
        half = p.travel / 2 / arm
        start, end = centre - half, centre + half
        reposition = min(rheo.config.max_speed, 1e-3)
        overlaps = p.levels
        legs = len(overlaps) * len(p.speeds) * 2
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
                for speed in p.speeds:
                    for direction, target in ((1.0, end), (-1.0, start)):
                        ctx.checkpoint()
                        rec.labels = {"pass": float(done), "direction": direction,
                                      "speed_m_s": speed, "overlap_m": depth}
                        rec.turn_to(target, speed)
                        rec.labels = {**rec.labels, "pass": -1.0}
                        rec.dwell(p.wait)
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
        return LadderResult(touch, centre, passes)
