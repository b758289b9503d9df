"""A recorded ramp-and-hold analysed whole: its hold, G(t) over it, and its Prony fits.

Arrays in, a :class:`HoldAnalysis` out; no files, no text beyond error messages. The report
(:mod:`gelrig.instrument.reports.hold`) and ``gelrig analyze`` format it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from gelrig.instrument.analysis.hold import HoldSpan, find_hold
from gelrig.instrument.analysis.relaxation import (
    MIN_HOLD_SAMPLES,
    FirstTouch,
    RelaxationFit,
    estimate_first_touch,
    fit_hold,
    loading_law,
    modulus_history,
)
from gelrig.instrument.core.binning import bin_means
from gelrig.instrument.core.errors import ConfigError, GelrigError
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.material import Material

#: The ramp must reach this fraction of the planned hold overlap, else there is no hold.
MIN_DEPTH_FRACTION = 0.9
#: A hold recorded for less than this fraction of the planned duration is truncated.
MIN_DURATION_FRACTION = 0.98


class NoHold(GelrigError):
    """The record holds no hold that can be fitted (too short, or never reached the depth)."""


@dataclass(frozen=True)
class MeasuredOverlap:
    """The overlap the hold fit uses: plate position less the first touch refitted on the
    step's own ramp, less the load cell's deflection (m; ``compliance`` in m/N).

    ``touch`` is None (and ``recorded_touch`` used) when the ramp could not be fitted;
    ``why`` then says why. ``held`` is the mean measured overlap over the hold.
    """

    recorded_touch: float
    touch: FirstTouch | None
    compliance: float
    held: float
    why: str = ""

    @property
    def stderr(self) -> float:
        """Standard error (m) of the first touch used, so of the overlap: the ramp refit's;
        0 when the recorded touch stands in (its uncertainty is not known here)."""
        if self.touch is None or not math.isfinite(self.touch.stderr):
            return 0.0
        return self.touch.stderr

    @property
    def first_touch(self) -> float:
        """The first touch used (m): the ramp's, else the recorded one."""
        return self.touch.position if self.touch is not None else self.recorded_touch


def ramp_start(position: FloatArray, hold_start: int) -> int:
    """First sample of the ramp that ends at ``hold_start``: the plate moves forward without a
    pause from there (before it, the tare's dwell or whatever came earlier)."""
    step = np.diff(position[: hold_start + 1])
    still = np.flatnonzero(step <= 0)
    return int(still[-1]) + 1 if still.size else 0


def measured_overlap(position: ArrayLike, force: ArrayLike, delta: ArrayLike, hold_start: int,
                     compliance: float = 0.0, trusted: ArrayLike | None = None,
                     time: ArrayLike | None = None, material: Material | None = None
                     ) -> tuple[MeasuredOverlap, FloatArray]:
    """Refit first touch on the ramp before ``hold_start`` and return it with the measured
    overlap at every sample (docs/decisions/0160). ``trusted`` (per sample; default all)
    leaves samples whose position was flagged out of the refit (ADR 0241). ``material``
    (with the samples' ``time``, s): the material as fitted, whose loading law then replaces
    the first-order softening (ADR 0375).

    The recorded ``delta`` is the position less the contact search's estimate, from a fast
    probe with few samples in contact; the ramp crosses the same touch slowly with hundreds.
    """
    f = np.asarray(force, dtype=float)
    z_stage = np.asarray(position, dtype=float)
    offsets = z_stage - np.asarray(delta, dtype=float)
    offsets = offsets[np.isfinite(offsets)]
    recorded = float(np.median(offsets)) if offsets.size else math.nan
    z = z_stage - compliance * f  # where the plate is, the load cell's deflection taken off
    touch: FirstTouch | None = None
    why = ""
    if 0 < hold_start < z.size:
        start = ramp_start(z_stage, hold_start)
        ramp = slice(start, hold_start)
        good = np.isfinite(z[ramp]) & np.isfinite(f[ramp])
        if trusted is not None:
            good &= np.asarray(trusted, dtype=bool)[ramp]
        try:
            law = None
            if material is not None and time is not None:
                law = loading_law(np.asarray(time, dtype=float)[ramp][good], material)
            touch = estimate_first_touch(z[ramp][good], f[ramp][good], relaxing=True,
                                         quantised=True, law=law)
            if not (recorded - 1e-3 < touch.position < float(z[hold_start])):
                why = (f"the ramp's first touch {touch.position * 1e3:.4f} mm is not on the "
                       "ramp")
                touch = None
        except ConfigError as exc:
            why = f"first touch not refitted on the ramp ({exc})"
    else:
        why = "no ramp before the hold"
    overlap = z - (touch.position if touch is not None else recorded)
    held = float(np.mean(overlap[hold_start:])) if overlap.size > hold_start else math.nan
    return MeasuredOverlap(recorded, touch, compliance, held, why), overlap


@dataclass(frozen=True)
class HoldResiduals:
    """G(t) over the hold as equal-count bin means, and each fit's residual there (Pa, s)."""

    t: FloatArray
    g: FloatArray
    residuals: tuple[FloatArray, ...]


@dataclass(frozen=True)
class HoldAnalysis:
    """A hold and its fits: ``t`` (s from the hold start) and ``g`` (Pa) are G(t) over it.

    ``fits`` holds the fits that succeeded, in the order of the requested term counts;
    ``fit_errors`` maps the term count of each one that failed to its reason.
    """

    span: HoldSpan
    radius: float
    depth: float
    duration: float
    planned: float
    t: FloatArray
    g: FloatArray
    fits: tuple[RelaxationFit, ...]
    fit_errors: dict[int, str] = field(default_factory=dict)
    overlap: MeasuredOverlap | None = None

    @property
    def samples(self) -> int:
        """Samples of G(t) over the hold."""
        return int(self.t.size)

    @property
    def truncated(self) -> bool:
        """True when the hold was recorded for visibly less than planned."""
        return math.isfinite(self.planned) and self.duration < MIN_DURATION_FRACTION * self.planned

    def residuals(self, bins: int) -> HoldResiduals:
        """G(t) in ``bins`` equal-count bin means with every fit's residual at them."""
        tb, gb = bin_means(self.t, self.g, bins)
        return HoldResiduals(tb, gb, tuple(gb - fit.model(tb) for fit in self.fits))


def analyse_hold(
    t: ArrayLike,
    force: ArrayLike,
    delta: ArrayLike,
    radius: float,
    depth: float,
    planned: float = math.nan,
    terms: Sequence[int] = (1, 2),
    nu: float = 0.5,
    position: ArrayLike | None = None,
    compliance: float = 0.0,
) -> HoldAnalysis:
    """Find the hold of a ramp-and-hold step, back-calculate G(t) over it and fit it with each
    number of ``terms``; ``depth`` (m) is the planned hold overlap, ``planned`` (s) the hold
    time. With the plate ``position`` (m), G(t) uses the measured overlap instead of ``depth``
    (:func:`measured_overlap`; ``compliance`` in m/N).

    Samples where the force or the overlap is not finite are left out. Raises :class:`NoHold`
    when the record is too short or the ramp never came within 10 % of ``depth``.
    """
    t_all = np.asarray(t, dtype=float)
    f_all = np.asarray(force, dtype=float)
    d_all = np.asarray(delta, dtype=float)
    ok = np.isfinite(d_all) & np.isfinite(f_all)
    z_all = None if position is None else np.asarray(position, dtype=float)
    if z_all is not None:
        ok &= np.isfinite(z_all)
    t_ok, f_ok, d_ok = t_all[ok], f_all[ok], d_all[ok]
    if t_ok.size < MIN_HOLD_SAMPLES:
        raise NoHold("no hold data to fit")
    span = find_hold(delta=d_ok)
    if span.samples < MIN_HOLD_SAMPLES or span.top < MIN_DEPTH_FRACTION * depth:
        raise NoHold(f"the ramp never reached the hold depth {depth * 1e3:.3f} mm "
                     f"(deepest {span.top * 1e3:.3f} mm)")
    # The retract after the hold is not part of it.
    t_ok, f_ok, d_ok = t_ok[: span.end], f_ok[: span.end], d_ok[: span.end]
    measured: MeasuredOverlap | None = None
    held: float | FloatArray = depth
    if z_all is not None:
        measured, overlap = measured_overlap(z_all[ok][: span.end], f_ok, d_ok, span.start,
                                             compliance)
        held = overlap
    errors: dict[int, str] = {}
    by_terms: dict[int, RelaxationFit] = {}
    for n in sorted(set(terms), reverse=True):  # a fit carries those with fewer terms
        if n in by_terms:
            continue
        try:
            fit: RelaxationFit | None = fit_hold(
                t_ok, f_ok, radius, held, nu, terms=n, delta=d_ok,
                overlap_stderr=measured.stderr if measured is not None else 0.0)
        except ConfigError as exc:
            errors[n] = str(exc)
            continue
        while fit is not None:
            by_terms.setdefault(len(fit.relax), fit)
            fit = fit.fewer
    fits = [by_terms[n] for n in terms if n in by_terms]
    t0 = float(t_ok[span.start])
    hold = t_ok >= t0
    # Without a fit the depth may be what failed (G(t) needs it > 0): no G(t) then.
    g = (modulus_history(f_ok[hold], held if np.ndim(held) == 0 else np.asarray(held)[hold],
                         radius, nu)
         if fits else np.full(hold.sum(), math.nan))
    return HoldAnalysis(
        span=span, radius=radius, depth=depth, duration=float(t_ok[-1] - t0), planned=planned,
        t=t_ok[hold] - t0, g=g, fits=tuple(fits), fit_errors=errors, overlap=measured,
    )
