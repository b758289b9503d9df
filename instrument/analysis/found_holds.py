"""Every hold of a compression record analysed, whatever step recorded it.

:func:`gelrig.instrument.analysis.segments.find_holds` finds the holds; a relaxation hold is
fitted like a ramp_hold step's (:func:`~gelrig.instrument.analysis.hold_analysis.analyse_hold`
on the record from the end of the hold before it, so its ramp refits first touch), a creep
hold by :func:`~gelrig.instrument.analysis.creep.fit_creep`. :func:`hold_row` and
:func:`relaxation_row` give the one row per hold that the series report compares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from gelrig.instrument.analysis.creep import CreepFit, Uncertain, fit_creep
from gelrig.instrument.analysis.hold_analysis import (
    HoldAnalysis,
    NoHold,
    analyse_hold,
    measured_overlap,
    ramp_start,
)
from gelrig.instrument.analysis.model_fit import Z95
from gelrig.instrument.analysis.relaxation import FirstTouch, RelaxationFit, with_scale_stderr
from gelrig.instrument.analysis.segments import MIN_DURATION, Segment, find_holds
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.material import Material

#: The columns a record needs for its holds to be found.
NEEDED = ("t_s", "position_m", "force_N")
#: Samples before the ramp that the fit's record keeps (the baseline before contact).
BASELINE_SAMPLES = 200
#: The creep's loading ends where the force first reaches this fraction of the held force.
LOADED = 0.97
#: At most this many refits of a creep's first touch with the fitted material's loading law
REFINE_TOUCH = 4


@dataclass(frozen=True)
class FoundHold:
    """One hold of a record: where it is, its overlap (m) and force (N), and its fit (a
    relaxation :class:`HoldAnalysis` or a :class:`CreepFit`); ``not_resolved`` says why
    there is no fit to show ("" when there is)."""

    segment: Segment
    overlap: float
    force: float
    relaxation: HoldAnalysis | None = None
    creep: CreepFit | None = None
    not_resolved: str = ""
    touch: tuple[float, float] | None = None

    @property
    def first_touch(self) -> tuple[float, float] | None:
        """First touch and its standard error (m) refitted on the ramp into this hold, None
        when it was not."""
        if self.relaxation is not None and self.relaxation.overlap is not None \
                and self.relaxation.overlap.touch is not None:
            return (self.relaxation.overlap.first_touch, self.relaxation.overlap.stderr)
        return self.touch

    @property
    def kind(self) -> str:
        """"relaxation" or "creep"."""
        return self.segment.kind


def _overlap(cols: Mapping[str, FloatArray], start: int, end: int) -> FloatArray | None:
    d = cols.get("delta_m")
    return None if d is None else np.asarray(d[start:end], dtype=float)


def analyse_found(cols: Mapping[str, FloatArray], segment: Segment, previous_end: int,
                  radius: float, compliance: float = 0.0,
                  touch: tuple[float, float] | None = None) -> FoundHold:
    """Fit one hold of ``cols``; ``radius`` (m) the sphere's. The fit's record starts on the
    baseline before the plate last came into contact, so a hold after another (ended at
    sample ``previous_end``, the plate still in contact) keeps the whole loading history.
    First touch is refitted on the ramp when the ramp into this hold starts clear of the
    sphere; otherwise ``touch`` (m, and its standard error: refitted for an earlier hold of
    the record, which adds its error to the moduli's) stands for it, else the recorded overlap
    (the contact search's)."""
    t = np.asarray(cols["t_s"], dtype=float)
    z = np.asarray(cols["position_m"], dtype=float)
    f = np.asarray(cols["force_N"], dtype=float)
    s = segment
    level_f = float(np.mean(f[s.start:s.end]))
    if "delta_m" not in cols:
        return FoundHold(s, math.nan, level_f,
                         not_resolved="no overlap column (delta_m) to fit the hold with")
    d_all = np.asarray(cols["delta_m"], dtype=float)
    clear = np.flatnonzero(d_all[:s.start] <= 0)
    before, refit = 0, False
    if clear.size:  # from the dwell before the ramp that crossed first touch
        crossing = int(clear[-1])
        before = max(0, ramp_start(z[:crossing + 1], crossing) - BASELINE_SAMPLES)
        refit = crossing >= previous_end
    delta = d_all[before:s.end]
    touch_err = 0.0
    if not refit and touch is not None:
        delta = z[before:s.end] - compliance * f[before:s.end] - touch[0]
        touch_err = touch[1]
    held = float(np.median(delta[s.start - before:]))
    if s.kind == "relaxation":
        return _relaxation(t, f, z, s, before, delta, held, level_f, radius, compliance,
                           refit, touch_err)
    return _creep(t, f, z, s, before, delta, level_f, radius, compliance, refit, touch_err)


def _relaxation(t: FloatArray, f: FloatArray, z: FloatArray, s: Segment, before: int,
                delta: FloatArray, held: float, level_f: float, radius: float,
                compliance: float, refit: bool, touch_err: float) -> FoundHold:
    """A relaxation hold fitted like a ramp_hold step's."""
    if float(np.nanmax(delta)) > held + 1e-6:
        return FoundHold(s, held, level_f, not_resolved="reached by unloading (the "
                         "overlap was larger before it): not a relaxation from a ramp")
    try:
        hold = analyse_hold(t[before:s.end], f[before:s.end], delta, radius, held,
                            s.duration, position=z[before:s.end] if refit else None,
                            compliance=compliance)
    except (NoHold, ConfigError) as exc:
        return FoundHold(s, held, level_f, not_resolved=str(exc))
    if not hold.fits:
        why = "; ".join(hold.fit_errors.values()) or "no fit"
        return FoundHold(s, held, level_f, hold, not_resolved=why)
    if touch_err > 0:  # the earlier hold's first touch: its error scales the moduli
        hold = replace(hold, fits=tuple(with_scale_stderr(fit, 1.5 * touch_err / held)
                                        for fit in hold.fits))
    measured = hold.overlap.held if hold.overlap is not None else held
    why = "" if hold.fits[-1].resolved.is_resolved else hold.fits[-1].resolved.reason
    return FoundHold(s, measured, level_f, hold, not_resolved=why)


def _creep(t: FloatArray, f: FloatArray, z: FloatArray, s: Segment, before: int,
           delta: FloatArray, level_f: float, radius: float, compliance: float, refit: bool,
           touch_err: float) -> FoundHold:
    """A creep hold: the ramp ends where the force first reaches the held level. With the
    ramp recorded from clear of the sphere, its first-touch fit gives the overlap and the
    force's baseline (what the tare left), each with its error, which the creep fit carries
    (ADR 0375)."""
    k = s.start - before
    rel = np.flatnonzero(f[before:s.start + 1] >= LOADED * level_f)
    loaded = int(rel[0]) if rel.size else k
    tt, zz, ff = t[before:s.end], z[before:s.end], f[before:s.end]
    ov, inputs, base = delta + 0.0, Uncertain(touch_err), 0.0
    found: FirstTouch | None = None
    refit = refit and loaded > 0
    if refit:
        overlap, ov = measured_overlap(zz, ff, delta, loaded, compliance)
        found = overlap.touch
        inputs = Uncertain(overlap.stderr)
    if found is not None:
        base, inputs = found.baseline, _inputs(found)

    def fitted(ov: FloatArray, base: float, inputs: Uncertain) -> CreepFit:
        contact = np.flatnonzero(ov[:k] <= 0)
        return fit_creep(tt, ov, ff - base, k, radius,
                         loading=int(contact[-1]) if contact.size else None, inputs=inputs)

    try:
        fit = fitted(ov, base, inputs)
    except ConfigError as exc:
        return FoundHold(s, float(np.mean(ov[k:])), level_f, not_resolved=str(exc))
    # The ramp's first touch again, with the material just fitted as its loading law in place
    # of the first-order softening, then the creep again; until the touch settles (ADR 0375)
    for _ in range(REFINE_TOUCH if found is not None else 0):
        if found is None or not fit.is_resolved or fit.partial:
            break
        material = Material.of(fit.values["G_e"], [(fit.values["G_1"], fit.values["tau_1"])])
        overlap, ov_next = measured_overlap(zz, ff, delta, loaded, compliance, time=tt,
                                            material=material)
        if overlap.touch is None:
            break
        try:
            fit_next = fitted(ov_next, overlap.touch.baseline, _inputs(overlap.touch))
        except ConfigError:
            break
        moved = abs(overlap.touch.position - found.position)
        ov, fit, found = ov_next, fit_next, overlap.touch
        if moved <= 0.02 * found.stderr:
            break
    touch = None if found is None else (found.position, found.stderr)
    return FoundHold(s, float(np.mean(ov[k:])), level_f, creep=fit,
                     not_resolved=fit.not_resolved, touch=touch)


def _inputs(found: FirstTouch) -> Uncertain:
    """A touch fit's errors as the creep fit's input errors."""
    corr = found.correlation if math.isfinite(found.correlation) else 0.0
    return Uncertain(found.stderr, found.baseline_stderr, corr)


def holds_of(cols: Mapping[str, FloatArray], radius: float, resolution: float = 1e-8,
             compliance: float = 0.0, min_duration: float = MIN_DURATION) -> list[FoundHold]:
    """Every hold of a record with the plate position and force columns, fitted (none when
    the columns are not there)."""
    if not all(c in cols for c in NEEDED):
        return []
    segments = find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols.get("delta_m"),
                          resolution, min_duration)
    out: list[FoundHold] = []
    previous, touch = 0, None
    for s in segments:
        hold = analyse_found(cols, s, previous, radius, compliance, touch)
        out.append(hold)
        touch = hold.first_touch if hold.first_touch is not None else touch
        previous = s.end
    return out


def _interval(row: dict[str, object], name: str, value: float, stderr: float) -> None:
    ok = math.isfinite(value)
    row[name] = value if ok else None
    row[f"{name}_se"] = stderr if ok and math.isfinite(stderr) else None
    lo = value - Z95 * stderr if ok and math.isfinite(stderr) else None
    row[f"{name}_lo"] = lo
    row[f"{name}_hi"] = value + Z95 * stderr if lo is not None else None


def relaxation_row(fit: RelaxationFit | None, overlap: float, diameter: float, duration: float,
                   why: str = "") -> dict[str, object]:
    """A series row of a relaxation hold: the reported fit's G_e, G_1 (ramp-corrected when the
    overlap history was there: the material's, comparable across holds whatever their ramp),
    tau_1 with 95 % intervals (value +- 1.96 s.e.); no values when it is not resolved."""
    row: dict[str, object] = {"hold": "relaxation", "overlap_m": overlap,
                              "strain": overlap / diameter, "hold_s": duration}
    shown = fit.resolved if fit is not None else None
    ok = shown is not None and shown.is_resolved and not why
    values = {"G_e": math.nan, "G_1": math.nan, "tau_1": math.nan, "tau_c": math.nan}
    errors = dict.fromkeys(values, math.nan)
    if ok and shown is not None:
        values.update(G_e=shown.g_e, G_1=shown.relax[0].g, tau_1=shown.relax[0].tau)
        errors.update({k: shown.stderr.get(k, math.nan) for k in ("G_e", "G_1", "tau_1")})
        corrected = shown.extra.get("relax_ramp_corrected")
        if isinstance(corrected, list) and corrected and shown.relax[0].g > 0:
            # the material's G_1, not the hold start's: the ramp relaxed part of it; its
            # standard error scales alike
            ratio = float(corrected[0]["G"]) / shown.relax[0].g
            values["G_1"] *= ratio
            errors["G_1"] *= ratio
    for name, value in values.items():
        _interval(row, name, value, errors[name])
    row["resolved"] = ok
    row["not_resolved"] = "" if ok else (why or (shown.reason if shown is not None else
                                                 "no fit"))
    return row


def hold_row(hold: FoundHold, diameter: float) -> dict[str, object]:
    """A series row of a found hold (:func:`relaxation_row`, or the creep fit's G_e, tau_c
    and, with the loading recorded, G_1 and tau_1)."""
    s = hold.segment
    if hold.kind == "relaxation":
        fit = hold.relaxation.fits[-1] if hold.relaxation and hold.relaxation.fits else None
        return relaxation_row(fit, hold.overlap, diameter, s.duration, hold.not_resolved
                              if fit is None else "")
    row: dict[str, object] = {"hold": "creep", "overlap_m": hold.overlap,
                              "strain": hold.overlap / diameter, "hold_s": s.duration}
    creep = hold.creep
    for name in ("G_e", "G_1", "tau_1", "tau_c"):
        value = creep.value(name) if creep is not None else math.nan
        err = creep.stderr.get(name, math.nan) if creep is not None else math.nan
        _interval(row, name, value, err)
    row["resolved"] = creep is not None and creep.is_resolved
    reason = hold.not_resolved or (creep.partial if creep is not None else "")
    row["not_resolved"] = reason
    return row
