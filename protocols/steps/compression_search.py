"""Compression contact search: probe towards the sphere until the force crosses a threshold,
estimate first touch from the approach curve, retract, repeat to confirm (paper: 0.5 mm moves
at 0.3 mm/s)."""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from gelrig.instrument.analysis.relaxation import estimate_first_touch
from gelrig.instrument.core.errors import ConfigError, InstrumentError
from gelrig.instrument.core.fields import Field, param
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.caps import stage_position_error, stage_speed_error
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import CompressionLimits, CompressionRig
from gelrig.protocols.steps.acquire import COLUMNS, ForceRecorder
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
class SearchParams(StepParams):
    """Parameters of a compression contact search (paper: 0.5 mm probes at 0.3 mm/s)."""

    start: float = param(Field("start", "m", 0.0, 0.0, 25e-3, display="mm",
                               help="stage position to start from, clear of the sphere"))
    probe: float = param(Field("probe", "m", 0.5e-3, 0.0, 5e-3, lo_open=True, display="mm",
                               help="travel of one probe move"))
    speed: float = param(Field("speed", "m/s", 0.3e-3, 0.0, 2.3e-3, lo_open=True,
                               display="mm/s", help="probe speed"))
    threshold: float = param(Field("threshold", "N", 5e-3, 0.0, 1.0, lo_open=True,
                                   help="force that means contact"))
    retract: float = param(Field("retract", "m", 0.5e-3, 0.0, 10e-3, lo_open=True, display="mm",
                                 help="back-off before each confirming approach, from the "
                                      "estimated touch"))
    confirm: float = param(Field("confirm", "", 2, 0, 10, integer=True,
                                 help="confirming approaches"))
    max_travel: float = param(Field("max_travel", "m", 15e-3, 0.0, 25e-3, lo_open=True,
                                    display="mm",
                                    help="give up after this much probing in one approach"))
    rate: float = param(Field("rate", "Hz", 100.0, 100.0, 20e3, help="force sample rate"))
    tare_time: float = param(Field("tare_time", "s", 1.0, 0.0, 60.0,
                                   help="force averaged for the tare (0: no tare)"))

    @property
    def approaches(self) -> int:
        return 1 + int(self.confirm)


@dataclass(frozen=True, repr=False)
class SearchResult(StepResult):
    """Where the plate first touches the sphere: the mean of the approaches' estimates."""

    first_touch_m: float
    first_touch_spread_m: float
    estimates_m: list[float]
    threshold_crossings_m: list[float]
    tare_offset_N: float  # noqa: N815 (run.json key: units in the name)

    def __repr__(self) -> str:
        n = len(self.estimates_m)
        return brief("SearchResult", f"first touch {mm(self.first_touch_m)}",
                     f"spread {mm(self.first_touch_spread_m)} over {n} approach"
                     f"{'' if n == 1 else 'es'}", f"tare {self.tare_offset_N * 1e3:.3f} mN")


class CompressionContactSearch(StepDefinition[CompressionRig, SearchParams, SearchResult]):
    """Probe towards the sphere until the force crosses a threshold, estimate first touch from
    each approach curve, retract and approach again to confirm."""

    kind: ClassVar[str] = "compression_contact_search"
    rig = CompressionRig
    Params = SearchParams
    Result = SearchResult
    description: ClassVar[str] = "contact search"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: SearchParams, limits: Limits) -> StepPlan:
        p = params
        approaches = p.approaches
        per_probe = p.probe / p.speed
        lines = [
            f"move to {p.start * 1e3:.3f} mm, tare for {p.tare_time:g} s",
            f"probe in {p.probe * 1e3:g} mm moves at {p.speed * 1e3:g} mm/s until "
            f"the force exceeds {p.threshold * 1e3:g} mN; {approaches} approaches "
            f"(retract {p.retract * 1e3:g} mm between)",
            "first touch from a Hertz fit of each approach curve; reports mean and spread",
        ]
        checks = []
        if isinstance(limits, CompressionLimits):
            ok = p.threshold < limits.max_force
            checks.append(PlanCheck("force", ok, f"threshold {p.threshold * 1e3:g} mN "
                                    f"{'<' if ok else '>='} force limit "
                                    f"{limits.max_force * 1e3:g} mN"))
        # Unknown until it runs: bound by the probing travel plus the confirming approaches.
        travel = p.max_travel + approaches * 2 * p.retract
        duration = (p.max_travel / p.speed
                    + approaches * (2 * p.retract / p.speed + per_probe) + p.tare_time)
        return StepPlan(duration, travel, lines, checks, samples=duration * p.rate)

    def preflight(self, params: SearchParams, rig: CompressionRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        caps = rig.stage_caps
        why = [stage_speed_error(params.speed, caps),
               stage_speed_error(rig.limits.fast_speed, caps),
               stage_position_error(params.start, caps)]
        return [w for w in why if w is not None]

    def run(self, ctx: StepContext[CompressionRig], params: SearchParams) -> SearchResult:
        p = params
        rig = ctx.rig
        stage, limits = rig.stage, rig.limits
        ctx.interlocks = rig.interlocks()
        if not stage.status().homed:  # before acquiring: homing is a blocking wait
            stage.home(wait=True)
        rec = ForceRecorder(ctx, p.rate)
        rec.start()
        stage.set_velocity(limits.fast_speed, limits.acceleration)
        stage.move_to(p.start, wait=False)
        rec.until_stopped()
        offset = rec.tare(p.tare_time) if p.tare_time > 0 else 0.0
        stage.set_velocity(p.speed, limits.acceleration)
        threshold = p.threshold
        estimates: list[float] = []
        crossings: list[float] = []
        approaches = p.approaches
        for attempt in range(approaches):
            ctx.checkpoint()
            rec.clear()
            travelled = 0.0
            crossing: int | None = None
            while crossing is None:
                if travelled >= p.max_travel - 1e-12:
                    raise InstrumentError(
                        f"no contact within {p.max_travel * 1e3:g} mm of probing "
                        f"(force never exceeded {threshold * 1e3:g} mN); check the start "
                        "position and the threshold")
                stage.move_by(p.probe, wait=False)
                crossing = rec.until_stopped(watch=(threshold,), stop_above=threshold)
                travelled += p.probe
                ctx.progress((attempt + min(travelled / p.max_travel, 0.99)) / approaches,
                             0.0, 0.0, f"approach {attempt + 1}/{approaches}",
                             position_m=stage.position())
            cols = rec.columns()
            z_cross = float(cols["position_m"][crossing])
            trusted = cols["position_flag"][: crossing + 1] == 0  # flagged: not where it was
            approach = (cols["position_m"][: crossing + 1][trusted],
                        cols["force_N"][: crossing + 1][trusted])
            touch = _touch_of(*approach, z_cross)
            if touch is None:
                raise InstrumentError(
                    f"first-touch fit failed on approach {attempt + 1}: no touch between "
                    f"the approach's start and the crossing at {z_cross * 1e3:.4f} mm (a "
                    "noisy or drifting force: raise the threshold or probe a shorter way)")
            estimates.append(touch)
            crossings.append(z_cross)
            rig.first_touch = touch  # where a safe stop retracts from
            stage.set_velocity(limits.fast_speed, limits.acceleration)
            stage.move_to(max(touch - p.retract, p.start), wait=False)
            rec.until_stopped()
            stage.set_velocity(p.speed, limits.acceleration)
        first_touch = statistics.fmean(estimates)
        spread = max(estimates) - min(estimates)
        ctx.progress(1.0, 0.0, 0.0, f"first touch {first_touch * 1e3:.4f} mm "
                     f"(spread {spread * 1e6:.1f} um)", first_touch_m=first_touch)
        return SearchResult(first_touch, spread, estimates, crossings, offset)


#: The approach the first-touch fit uses, before the touch: this many times the travel from
#: touch to the crossing, and at least :data:`MIN_WINDOW` (m). Millimetres of probing before
#: it hold only the baseline, and a baseline that wanders (a load cell's slow noise) over
#: them pulls the fit (a touch 77 mm early on a 0.5 mN, 0.5 s correlated part).
WINDOW_REACHES = 3.0
MIN_WINDOW = 0.2e-3


def _touch_of(z: FloatArray, f: FloatArray, z_cross: float) -> float | None:
    """First touch on one approach (m), fitted on the window before the crossing; None when
    no fit puts it on the approach (between its first sample and the crossing)."""
    def fitted(keep: NDArray[np.bool_]) -> float | None:
        try:
            touch = estimate_first_touch(z[keep], f[keep]).position
        except ConfigError:
            return None
        lowest = float(np.min(z[keep]))
        return touch if math.isfinite(touch) and lowest <= touch <= z_cross else None

    whole = fitted(np.ones(z.size, dtype=bool))
    reach = z_cross - whole if whole is not None else 1e-3
    keep = z >= z_cross - max((WINDOW_REACHES + 1) * reach, MIN_WINDOW)
    windowed = fitted(keep) if np.count_nonzero(keep) >= 8 else None
    return windowed if windowed is not None else whole
