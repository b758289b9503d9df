"""Shear contact search (paper): from a safe gap, lower 1 mm at a time and sweep for torque;
back off 1 mm; sweep at 0.5 rpm stopping at 0.2 mN m, else lower 0.1 mm and repeat; then
return to the reference angle.

The threshold fires well past first touch (Hertzian torque grows like overlap squared), so
the step also estimates the touch gap: full passes at the contact gap and one and two fine
steps below it give peak torques whose square roots fall linearly to zero at the touch gap.
It also locates the lower sphere's angle (the middle of the contact span of those passes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from gelrig.instrument.core.errors import InstrumentError
from gelrig.instrument.core.fields import Field, Where, param
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.sliding import speed_from_rpm
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
    mm,
)


@dataclass(frozen=True)
class ShearSearchParams(StepParams):
    """Parameters of the shear contact search (paper: 1 mm / 0.1 mm steps, 0.2 mN m at
    0.5 rpm)."""

    safe_gap: float = param(Field("safe_gap", "m", 8e-3, 0.0, 0.05, lo_open=True, display="mm",
                                  help="gap to start from"))
    coarse: float = param(Field("coarse", "m", 1e-3, 0.0, 5e-3, lo_open=True, display="mm",
                                help="coarse gap step"))
    fine: float = param(Field("fine", "m", 0.1e-3, 0.0, 1e-3, lo_open=True, display="mm",
                              help="fine gap step"))
    rpm: float = param(Field("rpm", "rpm", paper.CONTACT_SEARCH_RPM, 0.0, 10.0, lo_open=True,
                             help="the arm's sweep rate (revolutions per minute)"))
    threshold: float = param(Field("threshold", "N*m", paper.CONTACT_TORQUE, 0.0, 0.1,
                                   lo_open=True, help="contact torque"))
    reference_angle: float = param(Field("reference_angle", "rad", 0.0, -2 * math.pi,
                                         2 * math.pi,
                                         help="arm angle to sweep around and to return to"))
    sweep: float = param(Field("sweep", "m", 30e-3, 0.0, 0.15, lo_open=True, display="mm",
                               help="arc travel of one sweep at the arm, centred on the "
                                    "reference angle"))
    min_gap: float = param(Field("min_gap", "m", 0.0, 0.0, 0.05, display="mm",
                                 help="lowest gap the search may try"))
    interval: float = param(Field("interval", "s", 0.05, 0.001, 10.0,
                                  help="measurement-stream interval"))
    touch_passes: float = param(Field("touch_passes", "", 3, 0, 6, integer=True,
                                      help="full passes for the touch-gap estimate (0: skip; "
                                           "a line needs 2 or more)"))

    def validate(self, where: Where) -> None:
        if self.touch_passes == 1:  # one point cannot fix the line through sqrt(peak torque)
            raise where.error("touch_passes", 1, "allowed: 0 (skip) or 2 to 6")


@dataclass(frozen=True, repr=False)
class ShearSearchResult(StepResult):
    """Where the threshold fired, and (with touch passes) the touch gap and lower sphere."""

    contact_gap_m: float
    contact_angle_rad: float
    sweeps: int
    touch_gap_m: float = math.nan
    lower_sphere_angle_rad: float = math.nan
    touch_fit: dict[str, list[float]] = field(default_factory=dict)

    def __repr__(self) -> str:
        touch = (f"touch gap {mm(self.touch_gap_m)}" if math.isfinite(self.touch_gap_m)
                 else "")
        lower = (f"lower sphere at {math.degrees(self.lower_sphere_angle_rad):.2f} deg"
                 if math.isfinite(self.lower_sphere_angle_rad) else "")
        return brief("ShearSearchResult", f"contact at gap {mm(self.contact_gap_m)}, "
                     f"{math.degrees(self.contact_angle_rad):.2f} deg", touch, lower,
                     f"{self.sweeps} sweep{'' if self.sweeps == 1 else 's'}")


class ShearContactSearch(StepDefinition[ShearRig, ShearSearchParams, ShearSearchResult]):
    """Lower the arm's sphere step by step, sweeping for torque, until contact; then estimate
    the touch gap and the lower sphere's angle."""

    kind: ClassVar[str] = "shear_contact_search"
    rig = ShearRig
    Params = ShearSearchParams
    Result = ShearSearchResult
    description: ClassVar[str] = "contact search"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: ShearSearchParams, limits: Limits) -> StepPlan:
        p = params
        arm_speed = speed_from_rpm(p.rpm, paper.ARM)
        descents = (p.safe_gap - p.min_gap) / p.coarse
        sweep_time = 2 * p.sweep / arm_speed
        lines = [
            f"from gap {p.safe_gap * 1e3:g} mm: lower {p.coarse * 1e3:g} mm "
            "at a time, "
            f"sweep {p.sweep * 1e3:g} mm at {p.rpm:g} rpm for torque > "
            f"{p.threshold * 1e3:g} mN m",
            f"back off {p.coarse * 1e3:g} mm, then {p.fine * 1e3:g} mm steps "
            "stopping at the threshold; estimate the touch gap from "
            f"{int(p.touch_passes)} full passes",
        ]
        checks = []
        if isinstance(limits, ShearLimits):
            ok = p.threshold < limits.max_torque
            checks.append(PlanCheck("torque", ok, f"threshold {p.threshold * 1e3:g} mN m "
                                    f"{'<' if ok else '>='} torque limit "
                                    f"{limits.max_torque * 1e3:g} mN m"))
        duration = (descents + p.coarse / p.fine + p.touch_passes) \
            * sweep_time
        return StepPlan(duration, (descents + 10) * 2 * p.sweep, lines, checks,
                        samples=duration / p.interval)

    def preflight(self, params: ShearSearchParams, rig: ShearRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        config = rig.rheometer.config
        why = [arm_speed_error(speed_from_rpm(params.rpm, config.arm), config),
               rig.gap_error(params.safe_gap)]
        return [w for w in why if w is not None]

    def run(self, ctx: StepContext[ShearRig], params: ShearSearchParams) -> ShearSearchResult:
        p = params
        rig = ctx.rig
        rheo = rig.rheometer
        arm = rheo.config.arm
        speed = speed_from_rpm(p.rpm, arm)
        threshold = p.threshold
        ctx.interlocks = rig.interlocks()
        rec = ArmRecorder(ctx, p.interval, read_period=max(p.interval, 0.5))
        half = p.sweep / 2 / arm
        ref = p.reference_angle
        lo_angle, hi_angle = ref - half, ref + half
        try:
            if not rheo.status().gap_referenced:
                rheo.zero_gap()
            gap = p.safe_gap
            rheo.set_gap(gap)
            rec.turn_to(lo_angle, speed)
            sweeps = 0

            def sweep() -> float | None:
                nonlocal sweeps
                ctx.checkpoint()
                sweeps += 1
                start = rheo.angle()
                target = hi_angle if start < ref else lo_angle
                hit = rec.turn_to(target, speed, stop_above=threshold)
                if hit is not None:  # lift clear, return to the start side, lower again
                    rheo.set_gap(gap + p.coarse)
                    rec.turn_to(lo_angle if target == hi_angle else hi_angle, speed)
                    rheo.set_gap(gap)
                ctx.progress(0.0, 0.0, 0.0, f"sweep {sweeps} at gap {gap * 1e3:.3f} mm",
                             gap_m=gap)
                return hit

            while True:  # coarse
                if gap - p.coarse < p.min_gap - 1e-12:
                    raise InstrumentError(
                        f"no torque above {threshold * 1e3:g} mN m down to gap "
                        f"{p.min_gap * 1e3:g} mm; check the spheres and the sweep")
                gap -= p.coarse
                self._set_gap(rec, gap, lo_angle, hi_angle)
                if sweep() is not None:
                    break
            gap += p.coarse
            self._set_gap(rec, gap, lo_angle, hi_angle)
            while True:  # fine
                hit = sweep()
                if hit is not None:
                    break
                gap -= p.fine
                self._set_gap(rec, gap, lo_angle, hi_angle)
            contact_gap, contact_angle = gap, hit
            touch = self._touch_gap(ctx, rec, contact_gap, params, speed, lo_angle, hi_angle)
            rheo.set_gap(p.safe_gap)
            rec.turn_to(ref, speed)
        finally:
            rec.close()
        return ShearSearchResult(contact_gap, contact_angle, sweeps, **touch)

    @staticmethod
    def _set_gap(rec: ArmRecorder, gap: float, lo: float, hi: float) -> None:
        """Change the gap only with the arm clear of the contact (at a sweep end)."""
        angle = rec.rheo.angle()
        if not (angle <= lo + 1e-6 or angle >= hi - 1e-6):
            rec.turn_to(lo, abs(rec.rheo.config.max_speed) / 4)
        rec.rheo.set_gap(gap)

    @staticmethod
    def _touch_gap(
        ctx: StepContext[ShearRig], rec: ArmRecorder, contact_gap: float,
        params: ShearSearchParams, speed: float,
        lo: float, hi: float,
    ) -> dict[str, Any]:
        p = params
        passes = int(p.touch_passes)
        if passes == 0:
            return {}
        gaps, peaks, centres = [], [], []
        for k in range(passes):
            gap = contact_gap - k * p.fine / 2
            ShearContactSearch._set_gap(rec, gap, lo, hi)
            ctx.checkpoint()
            rec.kept, rec.keep = [], True
            start = rec.rheo.angle()
            rec.turn_to(hi if start < (lo + hi) / 2 else lo, speed)
            rec.keep = False
            cols = rec.columns()
            torque = np.abs(cols["torque_Nm"])
            base = float(np.median(torque[: max(3, torque.size // 10)]))
            signal = torque - base
            peak = float(signal.max())
            inside = np.flatnonzero(signal > 0.1 * peak)
            gaps.append(gap)
            peaks.append(max(peak, 0.0))
            if inside.size:
                centres.append(0.5 * (cols["angle_rad"][inside[0]] + cols["angle_rad"][inside[-1]]))
        root = np.sqrt(np.asarray(peaks))
        slope, intercept = np.polyfit(np.asarray(gaps), root, 1)
        touch_gap = float(-intercept / slope) if slope < 0 else math.nan
        return {"touch_gap_m": touch_gap, "lower_sphere_angle_rad":
                float(np.mean(centres)) if centres else math.nan,
                "touch_fit": {"gaps_m": gaps, "peak_torque_Nm": peaks}}
