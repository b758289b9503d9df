"""Analysis of recorded or modelled data: the hold's relaxation modulus and its Prony fit.

The paper back-calculates ``G(t) = F(t) / (K delta_hold^1.5)`` over a hold and fits
``G(t) = G_e + sum_i G_i exp(-t/tau_i)`` with one or two terms (physics.md section 3). The fit
here needs no starting values from the user: for every candidate set of time constants on a
logarithmic grid the amplitudes follow from linear least squares (variable projection), and
the best candidate seeds a nonlinear least-squares refinement that gives the uncertainties.

Note: the fitted amplitudes are those at the start of the hold. Part of each term relaxed
during the ramp, so they are smaller than the material's G_i; G_e and tau_i are unaffected.
:func:`ramp_corrected` undoes that using the recorded overlap history.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from instrument.binning import bin_means
from instrument.contact import (
    FloatArray,
    Material,
    RelaxationTerm,
    hereditary,
    hertz_power,
    hertz_prefactor,
)
from instrument.errors import ConfigError
from instrument.hold import find_hold

#: Bins the grid search averages the hold into (the refinement uses every sample).
_GRID_BINS = 600
#: Bins the nonlinear refinement uses at most (equal counts; exact for shorter records).
_REFINE_BINS = 20_000
#: Minimum number of hold samples a fit accepts.
MIN_HOLD_SAMPLES = 20


def modulus_history(
    force: ArrayLike, delta_hold: float | ArrayLike, radius: float, nu: float = 0.5
) -> FloatArray:
    """Back-calculated shear modulus G(t) = F / (K delta_hold^1.5) in Pa; ``delta_hold`` (m)
    is the held overlap, or the measured overlap at every sample."""
    d = np.asarray(delta_hold, dtype=float)
    if not np.all(d > 0):
        bad = float(np.min(d)) if d.size else math.nan
        raise ConfigError("depth", bad, "hold overlap must be > 0 m")
    k = hertz_prefactor(radius, nu)
    return np.asarray(force, dtype=float) / (k * d**1.5)


#: A term is resolved only if it lowers the BIC by at least this much (Kass and Raftery:
#: "very strong" evidence), ...
BIC_MARGIN = 10.0
#: ... every amplitude and time constant of the fit has a relative standard error below this ...
MAX_RELATIVE_ERROR = 0.25
#: ... and (two terms) the time constants differ by at least this factor.
MIN_TAU_RATIO = 2.0
#: Column-scaled Jacobians more ill-conditioned than this give undetermined standard errors.
MAX_CONDITION = 1e8
_ORDINAL = {1: "first", 2: "second"}
#: What the text forms print for a standard error the covariance does not determine.
UNDETERMINED = "undetermined"


def format_stderr(value: float, digits: int = 2) -> str:
    """A standard error for people: ``undetermined`` when it is NaN (singular or
    ill-conditioned covariance, a parameter at its bound), not 0 or a huge number presented as
    a value. (Exactly 0 only for a noise-free record.)"""
    if not (math.isfinite(value) and value >= 0):
        return UNDETERMINED
    return f"{value:.{digits}g}"


@dataclass(frozen=True)
class RelaxationFit:
    """Result of a Prony fit of G(t) over a hold (Pa, s; t measured from the hold start).

    Terms are ordered by time constant, longest first (tau_1 > tau_2). A standard error the
    covariance does not determine is NaN. ``terms_resolved`` counts the terms the data
    resolve (:func:`resolution`), ``not_resolved`` says why the next one is not ("" when all
    are), and ``fewer`` is the fit with one term less (None for one term).
    """

    g_e: float
    relax: tuple[RelaxationTerm, ...]
    t0: float
    rmse: float
    stderr: dict[str, float]
    n_samples: int
    extra: dict[str, object] = field(default_factory=dict)
    terms_resolved: int = -1
    not_resolved: str = ""
    fewer: RelaxationFit | None = None

    def model(self, t: ArrayLike) -> FloatArray:
        """G(t) of the fitted series, t from the hold start (s)."""
        return Material(self.g_e, self.relax).modulus(t)

    @property
    def bic(self) -> float:
        """Bayesian information criterion ``n ln(RSS/n) + k ln n`` on the raw samples."""
        n = self.n_samples
        return 2 * n * math.log(max(self.rmse, 1e-150)) + (1 + 2 * len(self.relax)) * math.log(n)

    @property
    def resolved(self) -> RelaxationFit:
        """The fit to report: this one, or the one with as many terms as the data resolve
        (at least one term)."""
        fit = self
        while len(fit.relax) > max(1, self.terms_resolved) and fit.fewer is not None:
            fit = fit.fewer
        return fit

    def _values(self) -> dict[str, object]:
        out: dict[str, object] = {
            "G_e": self.g_e,
            "relax": [{"G": term.g, "tau": term.tau} for term in self.relax],
            "t0_s": self.t0,
            "rmse": self.rmse,
            # JSON has no NaN: an undetermined standard error is null
            "stderr": {k: (v if math.isfinite(v) else None)
                       for k, v in self.stderr.items()},
        }
        out.update(self.extra)
        return out

    def as_dict(self) -> dict[str, object]:
        """The JSON form of the CLI contract (``gelrig fit relaxation``).

        The keys hold the reported fit (:attr:`resolved`); ``terms_resolved`` counts the
        resolved terms. When a requested term is not resolved, ``not_resolved`` says why and
        ``unresolved_fit`` holds the fit as requested.
        """
        shown = self.resolved
        out = shown._values()
        out["terms_resolved"] = max(self.terms_resolved, 0)
        if self.not_resolved:
            out["not_resolved"] = self.not_resolved
        if shown is not self:
            out["terms_requested"] = len(self.relax)
            out["unresolved_fit"] = self._values()
        return out


def resolution(fit: RelaxationFit, simpler_bic: float) -> str:
    """Why the last term of ``fit`` is not resolved, or "" when it is.

    ``simpler_bic`` is the BIC of the fit with one term less (for one term, a constant G).
    """
    if not all(math.isfinite(v) for v in fit.stderr.values()):
        return "covariance singular or ill-conditioned (standard errors undetermined)"
    gain = simpler_bic - fit.bic
    if gain < BIC_MARGIN:
        return f"BIC improvement {gain:.3g} < {BIC_MARGIN:g}"
    for n, term in enumerate(fit.relax, 1):
        for name, value in ((f"G_{n}", term.g), (f"tau_{n}", term.tau)):
            rel = fit.stderr[name] / abs(value) if value else math.inf
            if rel > MAX_RELATIVE_ERROR:
                return (f"{name} has a relative standard error of {rel:.3g} "
                        f"(> {MAX_RELATIVE_ERROR:g})")
    taus = [term.tau for term in fit.relax]
    for a, b in itertools.pairwise(taus):
        if a < MIN_TAU_RATIO * b:
            return (f"time constants {a:.4g} s and {b:.4g} s are less than "
                    f"{MIN_TAU_RATIO:g}x apart")
    return ""


def _design(t: FloatArray, taus: tuple[float, ...]) -> FloatArray:
    return np.column_stack([np.ones_like(t), *(np.exp(-t / tau) for tau in taus)])


def _grid_start(t: FloatArray, g: FloatArray, terms: int) -> tuple[float, ...]:
    """Best parameter vector (G_e, G_1, tau_1, ...) over a log grid of time constants."""
    span = float(t[-1] - t[0])
    dt = float(np.median(np.diff(t))) if t.size > 1 else span
    lo, hi = max(3 * dt, span * 1e-4), 20 * span
    taus = np.geomspace(lo, hi, 60 if terms == 1 else 32)
    best: tuple[float, tuple[float, ...], FloatArray] | None = None
    combo: tuple[float, ...]
    for candidate in itertools.combinations(taus[::-1].tolist(), terms):  # tau_1 > tau_2
        combo = tuple(candidate)
        a = _design(t, combo)
        coef = np.asarray(np.linalg.lstsq(a, g, rcond=None)[0], dtype=float)
        if np.any(coef[1:] < 0) or coef[0] <= 0:
            continue
        cost = float(np.sum((a @ coef - g) ** 2))
        if best is None or cost < best[0]:
            best = (cost, combo, coef)
    if best is None:  # nothing decays: fall back to a flat fit with slow, small terms
        combo = tuple(float(x) for x in np.geomspace(hi, lo, terms))
        coef = np.array([float(np.mean(g)), *([1e-6 * abs(float(np.mean(g)))] * terms)])
        best = (0.0, combo, coef)
    combo, coef = best[1], best[2]
    params: list[float] = [float(coef[0])]
    for amp, tau in zip(coef[1:], combo, strict=True):
        params += [max(float(amp), 1e-12), float(tau)]
    return tuple(params)


def fit_relaxation(
    t_hold: ArrayLike, g_hold: ArrayLike, terms: int = 1, t0: float = 0.0
) -> RelaxationFit:
    """Fit ``G(t) = G_e + sum_i G_i exp(-t/tau_i)`` (1 or 2 terms) with uncertainties, and say
    how many of its terms the data resolve.

    ``t`` (s) is measured from the hold start; ``t0`` is recorded in the result only. Every
    term count from 1 up to ``terms`` is fitted; term k is resolved when terms 1..k-1 are and
    :func:`resolution` finds no reason against it (docs/decisions/0160).
    """
    if terms not in (1, 2):
        raise ConfigError("terms", terms, "allowed: 1 or 2")
    t_all = np.asarray(t_hold, dtype=float)
    g_all = np.asarray(g_hold, dtype=float)
    ok = np.isfinite(t_all) & np.isfinite(g_all)
    t, g = t_all[ok], g_all[ok]
    if t.size < MIN_HOLD_SAMPLES:
        raise ConfigError("hold", t.size, f"need at least {MIN_HOLD_SAMPLES} samples to fit")
    n = t.size
    flat_rss = max(float(np.sum((g - np.mean(g)) ** 2)), 1e-300)
    simpler_bic = n * math.log(flat_rss / n) + math.log(n)  # constant G: one parameter
    return resolve_terms((_fit_terms(t, g, k, t0) for k in range(1, terms + 1)), simpler_bic)


def resolve_terms(fits: Iterable[RelaxationFit], simpler_bic: float) -> RelaxationFit:
    """The last of ``fits`` (1, 2, ... terms, each made when asked for) with the simpler fits
    chained as ``fewer`` and how many terms the data resolve: term k is resolved when terms
    1..k-1 are and :func:`resolution` finds no reason against it against the fit before it
    (the first against ``simpler_bic``, a constant G)."""
    fit: RelaxationFit | None = None
    resolved, why = 0, ""
    for k, made in enumerate(fits, start=1):
        fit = replace(made, fewer=fit)
        reason = resolution(fit, simpler_bic)
        if not why:
            if reason:
                why = f"{_ORDINAL[k]} term not resolved: {reason}"
            else:
                resolved = k
        simpler_bic = fit.bic
        fit = replace(fit, terms_resolved=resolved, not_resolved=why)
    if fit is None:
        raise ValueError("no fit to resolve")
    return fit


def _fit_terms(t: FloatArray, g: FloatArray, terms: int, t0: float) -> RelaxationFit:
    """The least-squares fit with exactly ``terms`` terms, ordered longest tau first."""
    start = _grid_start(*bin_means(t, g, _GRID_BINS), terms)
    # Refine on equal-count bin means: for white noise the same estimate and, from the
    # binned residuals, the same covariance, at a fraction of the cost for long records.
    t_raw, g_raw = t, g
    t, g = bin_means(t_raw, g_raw, _REFINE_BINS)

    def residual(p: FloatArray) -> FloatArray:
        out = np.full_like(t, p[0])
        for i in range(terms):
            out += p[1 + 2 * i] * np.exp(-t / p[2 + 2 * i])
        return out - g

    def jacobian(p: FloatArray) -> FloatArray:
        cols = [np.ones_like(t)]
        for i in range(terms):
            e = np.exp(-t / p[2 + 2 * i])
            cols += [e, p[1 + 2 * i] * e * t / p[2 + 2 * i] ** 2]
        return np.column_stack(cols)

    lower = [0.0] + [0.0, 1e-12] * terms
    result = least_squares(
        residual, np.array(start), jac=jacobian, bounds=(lower, np.inf), x_scale="jac"
    )
    p = result.x
    dof = max(1, t.size - p.size)
    err = standard_errors(result.jac, float(np.sum(result.fun**2)) / dof,
                          np.asarray(result.active_mask) != 0)
    pairs = sorted(
        ((float(p[1 + 2 * i]), float(p[2 + 2 * i]), i) for i in range(terms)),
        key=lambda item: -item[1],
    )
    relax = tuple(RelaxationTerm(amp, tau) for amp, tau, _ in pairs)
    stderr = {"G_e": float(err[0])}
    for n, (_, _, i) in enumerate(pairs, start=1):
        stderr[f"G_{n}"] = float(err[1 + 2 * i])
        stderr[f"tau_{n}"] = float(err[2 + 2 * i])
    raw_residual = Material(float(p[0]), relax).modulus(t_raw) - g_raw
    return RelaxationFit(
        g_e=float(p[0]),
        relax=relax,
        t0=t0,
        rmse=float(np.sqrt(np.mean(raw_residual**2))),
        stderr=stderr,
        n_samples=int(t_raw.size),
    )


def standard_errors(jac: ArrayLike, variance: float, at_bound: ArrayLike) -> FloatArray:
    """Standard errors from a least-squares Jacobian and the residual variance; NaN where the
    covariance does not determine them.

    A parameter at a bound, or one the model does not depend on, is undetermined; if what is
    left is ill-conditioned (column-scaled condition number above :data:`MAX_CONDITION`),
    all are.
    """
    j = np.asarray(jac, dtype=float)
    err = np.full(j.shape[1], math.nan)
    scale = np.linalg.norm(j, axis=0)
    keep = np.isfinite(scale) & (scale > 0) & ~np.asarray(at_bound, dtype=bool)
    if not keep.any() or not math.isfinite(variance):
        return err
    js = j[:, keep] / scale[keep]
    _, sv, vt = np.linalg.svd(js, full_matrices=False)
    if sv[-1] <= 0 or sv[0] / sv[-1] > MAX_CONDITION:
        return err
    cov = (vt.T / sv**2) @ vt * variance
    err[keep] = np.sqrt(np.diag(cov)) / scale[keep]
    return err


def fit_hold(
    time: ArrayLike,
    force: ArrayLike,
    radius: float,
    depth: float | ArrayLike,
    nu: float = 0.5,
    terms: int = 1,
    delta: ArrayLike | None = None,
    overlap_stderr: float = 0.0,
) -> RelaxationFit:
    """Find the hold in a ramp-and-hold record (:func:`instrument.hold.find_hold`; a retract
    after it is left out), back-calculate G(t) and fit it.

    ``overlap_stderr`` (m): the standard error of the measured overlap (of the first touch
    it is measured from), which scales every modulus alike; it is added to the moduli's
    standard errors (:func:`with_scale_stderr`).

    ``depth`` (m) is the held overlap, or the measured overlap at every sample of the record
    (stage position less first touch and the load cell's deflection: the hold fit then uses
    it sample by sample).

    With the overlap history, the result also carries the ramp-corrected amplitudes
    (``extra["relax_ramp_corrected"]``).
    """
    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    if t.shape != f.shape:
        raise ConfigError("force_N", f.size, f"needs one value per time sample ({t.size})")
    span = find_hold(delta=delta, force=f if delta is None else None)
    if span.samples < MIN_HOLD_SAMPLES:
        raise ConfigError("hold", span.samples, f"need at least {MIN_HOLD_SAMPLES} samples to fit")
    start, end = span.start, span.end
    t0 = float(t[start])
    d = np.asarray(depth, dtype=float)
    g = modulus_history(f[start:end], d[start:end] if d.ndim else float(d), radius, nu)
    fit = fit_relaxation(t[start:end] - t0, g, terms=terms, t0=t0)
    if overlap_stderr > 0:
        held = float(np.mean(d[start:end])) if d.ndim else float(d)
        fit = with_scale_stderr(fit, 1.5 * overlap_stderr / held)
    if delta is None:
        return fit
    return with_ramp_correction(fit, t[: start + 1], np.asarray(delta, float)[: start + 1])


def with_scale_stderr(fit: RelaxationFit, relative: float) -> RelaxationFit:
    """``fit`` (and its fits with fewer terms) with a relative uncertainty common to every
    modulus added in quadrature to G_e's and each G_i's standard error (tau's unchanged):
    the measured overlap's, ``1.5 sigma_delta / delta`` (G ~ F / delta^1.5). Kept as
    ``extra["scale_rel_stderr"]``. Called after the terms are resolved, so it changes no
    decision of the fit, only the intervals it reports (docs/decisions/0160 addendum)."""
    if not (math.isfinite(relative) and relative > 0):
        return fit
    fewer = None if fit.fewer is None else with_scale_stderr(fit.fewer, relative)
    values = {"G_e": fit.g_e} | {f"G_{k}": term.g for k, term in enumerate(fit.relax, 1)}
    stderr = dict(fit.stderr)
    for name, value in values.items():
        if name in stderr and math.isfinite(stderr[name]):
            stderr[name] = math.hypot(stderr[name], relative * abs(value))
    return replace(fit, stderr=stderr, fewer=fewer,
                   extra={**fit.extra, "scale_rel_stderr": relative})


def with_ramp_correction(fit: RelaxationFit, t_load: ArrayLike, delta_load: ArrayLike
                         ) -> RelaxationFit:
    """``fit`` (and its fits with fewer terms) carrying the ramp-corrected amplitudes in
    ``extra["relax_ramp_corrected"]``."""
    fewer = None if fit.fewer is None else with_ramp_correction(fit.fewer, t_load, delta_load)
    corrected = ramp_corrected(fit, t_load, delta_load)
    extra = {**fit.extra, "relax_ramp_corrected": [{"G": r.g, "tau": r.tau} for r in corrected]}
    return replace(fit, extra=extra, fewer=fewer)


def ramp_corrected(
    fit: RelaxationFit, t_load: ArrayLike, delta_load: ArrayLike
) -> tuple[RelaxationTerm, ...]:
    """Material amplitudes G_i from hold-start amplitudes, given the loading history.

    At the hold start each term holds ``h_i(t0) = int exp(-(t0 - s)/tau_i) dx(s)`` instead of
    ``x_hold``, so the fitted amplitude is ``G_i h_i(t0) / x_hold``.
    """
    tl = np.asarray(t_load, dtype=float)
    x = hertz_power(delta_load)
    if x.size == 0 or x[-1] <= 0:
        return fit.relax
    dt = np.diff(tl, prepend=tl[0])
    out = []
    for term in fit.relax:
        ratio = float(hereditary(dt, x, term.tau)[-1]) / float(x[-1])
        out.append(RelaxationTerm(term.g / ratio if ratio > 0 else term.g, term.tau))
    return tuple(out)


def contact_length(travel: ArrayLike, force: ArrayLike, threshold: float = 0.0) -> float:
    """Span of travel (m) from the first rise of ``force`` above ``threshold`` to its return.

    The deformed contact length l_c of physics.md section 2 (first rise to return to
    baseline); 0 if the force never rises.
    """
    x = np.asarray(travel, dtype=float)
    f = np.asarray(force, dtype=float)
    above = np.flatnonzero(f > threshold)
    if above.size == 0:
        return 0.0
    return float(abs(x[above[-1]] - x[above[0]]))


@dataclass(frozen=True)
class FirstTouch:
    """First-touch estimate from an approach curve: position (m), Hertz amplitude (N/m^1.5),
    baseline (N), residual (N), samples past touch, and the relaxation slope (1/m, 0 unless
    fitted)."""

    position: float
    amplitude: float
    baseline: float
    rmse: float
    n_contact: int
    softening: float = 0.0
    #: standard error of ``position`` (m) from the fit's covariance; NaN if undetermined
    stderr: float = math.nan


def estimate_first_touch(position: ArrayLike, force: ArrayLike, relaxing: bool = False
                         ) -> FirstTouch:
    """Where a plate first touched a sphere, from its force-displacement approach curve.

    Fits ``F = A d^1.5 (1 + c d) + b`` with ``d = max(z - z0, 0)`` by least squares, z0 free
    (docs/decisions/0160). Hertzian force is still tiny tens of micrometres past touch, so a
    threshold crossing overestimates z0; the fit uses the whole curve. Start values come from
    a line through ``F^(2/3)`` of the upper half. ``c`` is fitted only when ``relaxing``: on a
    slow ramp (tens of seconds) the material relaxes as the overlap grows, which a pure
    d^1.5 would absorb into z0 (0.9 um early on the paper's shell); on a fast probe c = 0.
    """
    z = np.asarray(position, dtype=float)
    f = np.asarray(force, dtype=float)
    if z.size < 8:
        raise ConfigError("approach", z.size, "need at least 8 samples on the approach curve")
    top = float(np.max(f))
    upper = f > 0.3 * top
    if np.count_nonzero(upper) < 3 or top <= 0:
        raise ConfigError("approach", top, "the force never rose above its noise")
    if np.unique(z[upper]).size < 3:  # a line through fewer positions is not determined
        raise ConfigError("approach", int(np.unique(z[upper]).size),
                          "the force rose over fewer than 3 plate positions; approach slower "
                          "or sample faster")
    slope, intercept = np.polyfit(z[upper], np.cbrt(f[upper]) ** 2, 1)
    if slope <= 0:
        raise ConfigError("approach", slope, "the force does not rise with the travel")
    z0_guess = -intercept / slope
    reach = max(float(np.max(z)) - z0_guess, 1e-9)  # travel past touch, for the scales

    def residual(p: FloatArray) -> FloatArray:
        d = np.maximum(z - p[0], 0.0)
        soft = 1.0 + p[3] * d if relaxing else 1.0
        return p[1] * d * np.sqrt(d) * soft + p[2] - f

    start = [z0_guess, slope**1.5, 0.0]
    scale = [1e-5, slope**1.5, max(top, 1e-9) * 1e-2]
    bounds = ([-np.inf] * 3, [np.inf] * 3)
    if relaxing:  # a gentle first-order softening, |c d| < 0.5 over the curve
        start.append(0.0)
        scale.append(0.01 / reach)
        bounds = ([*bounds[0], -0.5 / reach], [*bounds[1], 0.5 / reach])
    result = least_squares(residual, start, bounds=bounds, x_scale=scale)
    z0, amp, base = (float(v) for v in result.x[:3])
    return FirstTouch(z0, amp, base, float(np.sqrt(np.mean(result.fun**2))),
                      int(np.count_nonzero(z > z0)), float(result.x[3]) if relaxing else 0.0,
                      _first_stderr(result.jac, result.fun))


def _first_stderr(jac: FloatArray, residuals: FloatArray) -> float:
    """Standard error of the first parameter of a least-squares fit from its Jacobian and
    residuals (white noise); NaN when the covariance is singular."""
    n, k = jac.shape
    norms = np.linalg.norm(jac, axis=0)
    if n <= k or not np.all(np.isfinite(jac)) or not np.all(norms > 0):
        return math.nan
    scaled = jac / norms  # columns of unit length: the conditioning is the fit's, not units'
    normal = scaled.T @ scaled
    if np.linalg.cond(normal) > 1e12:
        return math.nan
    variance = float(np.sum(residuals**2)) / (n - k)
    return float(math.sqrt(max(variance * float(np.linalg.inv(normal)[0, 0]), 0.0))
                 / norms[0])
