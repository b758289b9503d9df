"""Ramp to a strain at a strain rate from first touch, hold, record, retract, fit the hold
(paper: 6 % of the diameter at 0.002 /s, hold 3000 s, 100 Hz or 1 kHz)."""

from __future__ import annotations

import math
from typing import Any, ClassVar

from instrument.analysis import fit_hold
from instrument.errors import GelrigError
from instrument.fields import Field
from protocols.context import StepContext
from protocols.interlocks import Interlock
from protocols.rig import CompressionLimits, CompressionRig
from protocols.steps.acquire import COLUMNS, ForceRecorder
from protocols.steps.base import Params, PlanCheck, StepDefinition, StepPlan


class RampHold(StepDefinition):
    kind: ClassVar[str] = "ramp_hold"
    rig: ClassVar[str] = "compression"
    description: ClassVar[str] = "ramp and hold"
    columns: ClassVar[dict[str, str]] = COLUMNS
    fields: ClassVar[tuple[Field, ...]] = (
        Field("diameter", "m", 18.63e-3, 0.0, 0.1, lo_open=True, help="sphere diameter"),
        Field("strain", "", 0.06, 0.0, 0.3, lo_open=True, help="hold overlap / diameter"),
        Field("strain_rate", "1/s", 0.002, 0.0, 1.0, lo_open=True, help="ramp speed / diameter"),
        Field("hold", "s", 3000.0, 0.0, 7 * 86400.0, help="hold duration"),
        Field("rate", "Hz", 100.0, 100.0, 20e3, help="force sample rate"),
        Field("approach", "m", 0.1e-3, 0.0, 5e-3,
              help="start the ramp this far before first touch"),
        Field("retract", "m", 2e-3, 0.0, 20e-3, help="back-off from first touch afterwards"),
        Field("first_touch", "m", math.nan, 0.0, 25e-3,
              help="stage position of first touch; default: from the contact search"),
        Field("tare_time", "s", 1.0, 0.0, 60.0,
              help="force averaged for a tare just before the ramp, clear of the sphere"),
        Field("terms", "", 2, 1, 2, integer=True,
              help="relaxation terms fitted (1 and up to this)"),
    )

    def plan(self, params: Params, limits: Any) -> StepPlan:
        depth = params["strain"] * params["diameter"]
        speed = params["strain_rate"] * params["diameter"]
        ramp = (depth + params["approach"]) / speed
        lines = [
            f"ramp {depth * 1e3:.4f} mm ({params['strain'] * 100:g} % of "
            f"{params['diameter'] * 1e3:g} mm) at {speed * 1e6:.2f} um/s "
            f"({params['strain_rate']:g} /s): {ramp:.1f} s",
            f"hold {params['hold']:g} s at {params['rate']:g} Hz "
            f"({int(params['hold'] * params['rate']):,} samples), retract "
            f"{params['retract'] * 1e3:g} mm, fit 1..{int(params['terms'])} relaxation terms",
        ]
        checks = []
        if isinstance(limits, CompressionLimits):
            ok = depth <= limits.max_overlap
            checks.append(PlanCheck("overlap", ok, f"depth {depth * 1e3:.4f} mm "
                                    f"{'<=' if ok else '>'} overlap limit "
                                    f"{limits.max_overlap * 1e3:g} mm"))
        back = 2 * params["retract"] / (limits.fast_speed if isinstance(limits, CompressionLimits)
                                        else 1e-3)
        travel = params["approach"] + depth + params["retract"] * 2
        return StepPlan(ramp + params["hold"] + back, travel, lines, checks)

    def run(self, ctx: StepContext, params: Params) -> dict[str, Any]:
        rig = ctx.rig
        assert isinstance(rig, CompressionRig)
        stage, limits = rig.stage, rig.limits
        touch = params["first_touch"]
        if math.isnan(touch):
            found = ctx.result("first_touch_m")
            if found is None:
                raise GelrigError("ramp_hold needs first_touch, or a contact search before it")
            touch = float(found)
        depth = params["strain"] * params["diameter"]
        speed = params["strain_rate"] * params["diameter"]
        ctx.interlocks = (
            Interlock("force", "force_N", limits.max_force, "N"),
            Interlock("overlap", "delta_m", limits.max_overlap, "m", absolute=False),
        )
        if not stage.status().homed:  # positions mean nothing before homing
            stage.home(wait=True)
        rec = ForceRecorder(ctx, params["rate"], first_touch=touch)
        rec.start()
        stage.set_velocity(limits.fast_speed, limits.acceleration)
        stage.move_to(touch - params["approach"], wait=False)
        rec.until_stopped()
        if params["tare_time"] > 0:  # clear of the sphere: zero the force here
            rec.tare(params["tare_time"])
        rec.clear()
        t_start = ctx.clock.now()
        stage.set_velocity(speed, limits.acceleration)
        stage.move_to(touch + depth, wait=False)
        ramp_time = (depth + params["approach"]) / speed
        while stage.is_moving():
            rec.read()
            elapsed = ctx.clock.now() - t_start
            ctx.progress(elapsed / (ramp_time + params["hold"]), elapsed,
                         ramp_time + params["hold"] - elapsed, "ramp")
        rec.dwell(params["hold"], progress=True, label="hold")
        cols = rec.columns()
        stage.set_velocity(limits.fast_speed, limits.acceleration)
        stage.move_to(max(touch - params["retract"], 0.0), wait=False)
        rec.keep = False
        rec.until_stopped()
        results: dict[str, Any] = {"first_touch_m": touch, "depth_m": depth, "speed_m_s": speed,
                                   "samples": int(cols["t_s"].size)}
        fits = []
        for terms in range(1, int(params["terms"]) + 1):
            try:
                fit = fit_hold(cols["t_s"], cols["force_N"], params["diameter"] / 2, depth,
                               terms=terms, delta=cols["delta_m"])
                fits.append(fit.as_dict())
            except GelrigError as exc:
                fits.append({"error": str(exc)})
        results["fits"] = fits
        return results
