"""Compression contact search: probe towards the sphere until the force crosses a threshold,
estimate first touch from the approach curve, retract, repeat to confirm (paper: 0.5 mm moves
at 0.3 mm/s)."""

from __future__ import annotations

import math
import statistics
from typing import Any, ClassVar

from instrument.analysis import estimate_first_touch
from instrument.errors import InstrumentError
from instrument.fields import Field
from protocols.context import StepContext
from protocols.interlocks import Interlock
from protocols.rig import CompressionLimits, CompressionRig
from protocols.steps.acquire import COLUMNS, ForceRecorder
from protocols.steps.base import Params, PlanCheck, StepDefinition, StepPlan


class CompressionContactSearch(StepDefinition):
    kind: ClassVar[str] = "compression_contact_search"
    rig: ClassVar[str] = "compression"
    description: ClassVar[str] = "contact search"
    columns: ClassVar[dict[str, str]] = COLUMNS
    fields: ClassVar[tuple[Field, ...]] = (
        Field("start", "m", 0.0, 0.0, 25e-3,
              help="stage position to start from, clear of the sphere"),
        Field("probe", "m", 0.5e-3, 0.0, 5e-3, lo_open=True, help="travel of one probe move"),
        Field("speed", "m/s", 0.3e-3, 0.0, 2.3e-3, lo_open=True, help="probe speed"),
        Field("threshold", "N", 5e-3, 0.0, 1.0, lo_open=True, help="force that means contact"),
        Field("retract", "m", 0.5e-3, 0.0, 10e-3, lo_open=True,
              help="back-off before each confirming approach, from the estimated touch"),
        Field("confirm", "", 2, 0, 10, integer=True, help="confirming approaches"),
        Field("max_travel", "m", 15e-3, 0.0, 25e-3, lo_open=True,
              help="give up after this much probing in one approach"),
        Field("rate", "Hz", 100.0, 100.0, 20e3, help="force sample rate"),
        Field("tare_time", "s", 1.0, 0.0, 60.0, help="force averaged for the tare (0: no tare)"),
    )

    def plan(self, params: Params, limits: Any) -> StepPlan:
        approaches = 1 + int(params["confirm"])
        per_probe = params["probe"] / params["speed"]
        lines = [
            f"move to {params['start'] * 1e3:.3f} mm, tare for {params['tare_time']:g} s",
            f"probe in {params['probe'] * 1e3:g} mm moves at {params['speed'] * 1e3:g} mm/s until "
            f"the force exceeds {params['threshold'] * 1e3:g} mN; {approaches} approaches "
            f"(retract {params['retract'] * 1e3:g} mm between)",
            "first touch from a Hertz fit of each approach curve; reports mean and spread",
        ]
        checks = []
        if isinstance(limits, CompressionLimits):
            ok = params["threshold"] < limits.max_force
            checks.append(PlanCheck("force", ok, f"threshold {params['threshold'] * 1e3:g} mN "
                                    f"{'<' if ok else '>='} force limit "
                                    f"{limits.max_force * 1e3:g} mN"))
        # Unknown until it runs: bound by the probing travel plus the confirming approaches.
        travel = params["max_travel"] + approaches * 2 * params["retract"]
        duration = (params["max_travel"] / params["speed"]
                    + approaches * (2 * params["retract"] / params["speed"] + per_probe)
                    + params["tare_time"])
        return StepPlan(duration, travel, lines, checks)

    def run(self, ctx: StepContext, params: Params) -> dict[str, Any]:
        rig = ctx.rig
        assert isinstance(rig, CompressionRig)
        stage, limits = rig.stage, rig.limits
        ctx.interlocks = (Interlock("force", "force_N", limits.max_force, "N"),)
        if not stage.status().homed:  # before acquiring: homing is a blocking wait
            stage.home(wait=True)
        rec = ForceRecorder(ctx, params["rate"])
        rec.start()
        stage.set_velocity(limits.fast_speed, limits.acceleration)
        stage.move_to(params["start"], wait=False)
        rec.until_stopped()
        offset = rec.tare(params["tare_time"]) if params["tare_time"] > 0 else 0.0
        stage.set_velocity(params["speed"], limits.acceleration)
        threshold = params["threshold"]
        estimates: list[float] = []
        crossings: list[float] = []
        approaches = 1 + int(params["confirm"])
        for attempt in range(approaches):
            ctx.checkpoint()
            rec.clear()
            travelled = 0.0
            crossing: int | None = None
            while crossing is None:
                if travelled >= params["max_travel"] - 1e-12:
                    raise InstrumentError(
                        f"no contact within {params['max_travel'] * 1e3:g} mm of probing "
                        f"(force never exceeded {threshold * 1e3:g} mN); check the start "
                        "position and the threshold")
                stage.move_by(params["probe"], wait=False)
                crossing = rec.until_stopped(watch=(threshold,), stop_above=threshold)
                travelled += params["probe"]
                ctx.progress((attempt + min(travelled / params["max_travel"], 0.99)) / approaches,
                             0.0, 0.0, f"approach {attempt + 1}/{approaches}",
                             position_m=stage.position())
            cols = rec.columns()
            z_cross = float(cols["position_m"][crossing])
            approach = cols["position_m"][: crossing + 1], cols["force_N"][: crossing + 1]
            touch = estimate_first_touch(*approach).position
            if not math.isfinite(touch) or touch > z_cross:
                raise InstrumentError(f"first-touch fit failed on approach {attempt + 1}")
            estimates.append(touch)
            crossings.append(z_cross)
            stage.set_velocity(limits.fast_speed, limits.acceleration)
            stage.move_to(max(touch - params["retract"], params["start"]), wait=False)
            rec.until_stopped()
            stage.set_velocity(params["speed"], limits.acceleration)
        first_touch = statistics.fmean(estimates)
        spread = max(estimates) - min(estimates)
        ctx.progress(1.0, 0.0, 0.0, f"first touch {first_touch * 1e3:.4f} mm "
                     f"(spread {spread * 1e6:.1f} um)", first_touch_m=first_touch)
        return {"first_touch_m": first_touch, "first_touch_spread_m": spread,
                "estimates_m": estimates, "threshold_crossings_m": crossings,
                "tare_offset_N": offset}
