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
from typing import Any, ClassVar

import numpy as np

from instrument.errors import InstrumentError
from instrument.fields import Field
from instrument.sliding import speed_from_rpm
from protocols.context import StepContext
from protocols.interlocks import Interlock
from protocols.rig import ShearLimits, ShearRig
from protocols.steps.arm import COLUMNS, ArmRecorder
from protocols.steps.base import Params, PlanCheck, StepDefinition, StepPlan


class ShearContactSearch(StepDefinition):
    kind: ClassVar[str] = "shear_contact_search"
    rig: ClassVar[str] = "shear"
    description: ClassVar[str] = "contact search"
    columns: ClassVar[dict[str, str]] = COLUMNS
    fields: ClassVar[tuple[Field, ...]] = (
        Field("safe_gap", "m", 8e-3, 0.0, 0.05, lo_open=True, help="gap to start from"),
        Field("coarse", "m", 1e-3, 0.0, 5e-3, lo_open=True, help="coarse gap step"),
        Field("fine", "m", 0.1e-3, 0.0, 1e-3, lo_open=True, help="fine gap step"),
        Field("rpm", "", 0.5, 0.0, 10.0, lo_open=True, help="sweep rate (rpm)"),
        Field("threshold", "N*m", 0.2e-3, 0.0, 0.1, lo_open=True, help="contact torque"),
        Field("reference_angle", "rad", 0.0, -2 * math.pi, 2 * math.pi,
              help="arm angle to sweep around and to return to"),
        Field("sweep", "m", 30e-3, 0.0, 0.15, lo_open=True,
              help="arc travel of one sweep at the arm, centred on the reference angle"),
        Field("min_gap", "m", 0.0, 0.0, 0.05, help="lowest gap the search may try"),
        Field("interval", "s", 0.05, 0.001, 10.0, help="measurement-stream interval"),
        Field("touch_passes", "", 3, 0, 6, integer=True,
              help="full passes for the touch-gap estimate (0: skip)"),
    )

    def plan(self, params: Params, limits: Any) -> StepPlan:
        arm_speed = speed_from_rpm(params["rpm"], 0.027)
        descents = (params["safe_gap"] - params["min_gap"]) / params["coarse"]
        sweep_time = 2 * params["sweep"] / arm_speed
        lines = [
            f"from gap {params['safe_gap'] * 1e3:g} mm: lower {params['coarse'] * 1e3:g} mm "
            "at a time, "
            f"sweep {params['sweep'] * 1e3:g} mm at {params['rpm']:g} rpm for torque > "
            f"{params['threshold'] * 1e3:g} mN m",
            f"back off {params['coarse'] * 1e3:g} mm, then {params['fine'] * 1e3:g} mm steps "
            "stopping at the threshold; estimate the touch gap from "
            f"{int(params['touch_passes'])} full passes",
        ]
        checks = []
        if isinstance(limits, ShearLimits):
            ok = params["threshold"] < limits.max_torque
            checks.append(PlanCheck("torque", ok, f"threshold {params['threshold'] * 1e3:g} mN m "
                                    f"{'<' if ok else '>='} torque limit "
                                    f"{limits.max_torque * 1e3:g} mN m"))
        duration = (descents + params["coarse"] / params["fine"] + params["touch_passes"]) \
            * sweep_time
        return StepPlan(duration, (descents + 10) * 2 * params["sweep"], lines, checks)

    def run(self, ctx: StepContext, params: Params) -> dict[str, Any]:
        rig = ctx.rig
        assert isinstance(rig, ShearRig)
        rheo = rig.rheometer
        arm = rheo.config.arm
        speed = speed_from_rpm(params["rpm"], arm)
        threshold = params["threshold"]
        ctx.interlocks = (
            Interlock("torque", "torque_Nm", rig.limits.max_torque, "N*m"),
            Interlock("normal force", "normal_force_N", rig.limits.max_normal_force, "N"),
        )
        rec = ArmRecorder(ctx, params["interval"], read_period=max(params["interval"], 0.5))
        half = params["sweep"] / 2 / arm
        ref = params["reference_angle"]
        lo_angle, hi_angle = ref - half, ref + half
        try:
            if not rheo.status().gap_referenced:
                rheo.zero_gap()
            gap = params["safe_gap"]
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
                    rheo.set_gap(gap + params["coarse"])
                    rec.turn_to(lo_angle if target == hi_angle else hi_angle, speed)
                    rheo.set_gap(gap)
                ctx.progress(0.0, 0.0, 0.0, f"sweep {sweeps} at gap {gap * 1e3:.3f} mm",
                             gap_m=gap)
                return hit

            while True:  # coarse
                if gap - params["coarse"] < params["min_gap"] - 1e-12:
                    raise InstrumentError(
                        f"no torque above {threshold * 1e3:g} mN m down to gap "
                        f"{params['min_gap'] * 1e3:g} mm; check the spheres and the sweep")
                gap -= params["coarse"]
                self._set_gap(rec, gap, lo_angle, hi_angle)
                if sweep() is not None:
                    break
            gap += params["coarse"]
            self._set_gap(rec, gap, lo_angle, hi_angle)
            while True:  # fine
                hit = sweep()
                if hit is not None:
                    break
                gap -= params["fine"]
                self._set_gap(rec, gap, lo_angle, hi_angle)
            contact_gap, contact_angle = gap, hit
            touch = self._touch_gap(ctx, rec, contact_gap, params, speed, lo_angle, hi_angle)
            rheo.set_gap(params["safe_gap"])
            rec.turn_to(ref, speed)
        finally:
            rec.close()
        return {"contact_gap_m": contact_gap, "contact_angle_rad": contact_angle,
                "sweeps": sweeps, **touch}

    @staticmethod
    def _set_gap(rec: ArmRecorder, gap: float, lo: float, hi: float) -> None:
        """Change the gap only with the arm clear of the contact (at a sweep end)."""
        angle = rec.rheo.angle()
        if not (angle <= lo + 1e-6 or angle >= hi - 1e-6):
            rec.turn_to(lo, abs(rec.rheo.config.max_speed) / 4)
        rec.rheo.set_gap(gap)

    @staticmethod
    def _touch_gap(
        ctx: StepContext, rec: ArmRecorder, contact_gap: float, params: Params, speed: float,
        lo: float, hi: float,
    ) -> dict[str, Any]:
        passes = int(params["touch_passes"])
        if passes == 0:
            return {}
        gaps, peaks, centres = [], [], []
        for k in range(passes):
            gap = contact_gap - k * params["fine"] / 2
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
