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
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from gelrig.instrument.analysis.hold import find_hold
from gelrig.instrument.analysis.quantiser import (
    DitheredQuantiser,
    Lattice,
    baseline_level,
    find_lattice,
    fit_sigma,
)
from gelrig.instrument.core.binning import bin_means
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.scipy_ext import siegel_slope
from gelrig.instrument.physics.contact import (
    FloatArray,
    Material,
    RelaxationTerm,
    hereditary,
    hertz_power,
    hertz_prefactor,
)

#: Bins the grid search averages the hold into (the refinement uses every sample).
_GRID_BINS = 600
#: combinations of the grid search solved one at a time after the batched shortlist
_SHORTLIST = 8
#: Bins the nonlinear refinement uses at most (equal counts; exact for shorter records).
_REFINE_BINS = 20_000
#: Minimum number of hold samples a fit accepts.
MIN_HOLD_SAMPLES = 20
#: Overlap (m) below which a sample is clear of the sphere: the baseline before contact.
BASELINE_CLEAR = 5e-6


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
    def is_resolved(self) -> bool:
        """Whether the data resolve every term of this fit (a fit not checked is not)."""
        return self.terms_resolved >= len(self.relax)

    @property
    def reason(self) -> str:
        """Why this fit is not a result ("" when it is resolved)."""
        if self.is_resolved:
            return ""
        return self.not_resolved or "terms not checked for resolution"

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

    def as_result(self) -> dict[str, object]:
        """``gelrig fit relaxation``'s JSON (ADR 0261: an unresolved fit is never a result):
        :meth:`as_dict` with ``resolved``, whether the reported fit is resolved. When not even
        its first term is, the top level holds no values: ``resolved`` is false,
        ``not_resolved`` says why, and the fit as requested is under ``unresolved_fit`` (not a
        result)."""
        out = self.as_dict()
        shown = self.resolved
        out["resolved"] = shown.is_resolved
        if not shown.is_resolved:
            for key in shown._values():
                out.pop(key, None)
            out["not_resolved"] = shown.reason
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
    """Best parameter vector (G_e, G_1, tau_1, ...) over a log grid of time constants: the
    first cheapest combination with no negative amplitude, shortlisted by
    :func:`_grid_batched`; every combination one at a time where that finds none."""
    span = float(t[-1] - t[0])
    dt = float(np.median(np.diff(t))) if t.size > 1 else span
    lo, hi = max(3 * dt, span * 1e-4), 20 * span
    taus = np.geomspace(lo, hi, 60 if terms == 1 else 32)
    best = _grid_batched(t, g, taus, terms)
    if best is None:
        best = _grid_each(t, g, taus, terms)
    if best is None:  # nothing decays: fall back to a flat fit with slow, small terms
        combo = tuple(float(x) for x in np.geomspace(hi, lo, terms))
        coef = np.array([float(np.mean(g)), *([1e-6 * abs(float(np.mean(g)))] * terms)])
        best = (combo, coef)
    combo, coef = best
    params: list[float] = [float(coef[0])]
    for amp, tau in zip(coef[1:], combo, strict=True):
        params += [max(float(amp), 1e-12), float(tau)]
    return tuple(params)


def _grid_batched(t: FloatArray, g: FloatArray, taus: FloatArray, terms: int
                  ) -> tuple[tuple[float, ...], FloatArray] | None:
    """The grid search of :func:`_grid_each` without solving 496 systems one by one (25 ms
    -> 0.9 ms at 200 bins, 26 -> 14 ms at 600): every combination's normal equations solved
    at once to shortlist the :data:`_SHORTLIST` cheapest that look valid,
    then those solved one at a time as before, so the start is the one-at-a-time search's
    unless its best lies outside the shortlist. None where the batch is singular."""
    down = taus[::-1]  # tau_1 > tau_2, the order of the one-at-a-time search
    combos = np.array(list(itertools.combinations(range(down.size), terms)), dtype=int)
    cols = np.ones((t.size, down.size + 1))
    cols[:, 1:] = np.exp(-t[:, None] / down[None, :])
    idx = np.concatenate([np.zeros((len(combos), 1), dtype=int), combos + 1], axis=1)
    gram = (cols.T @ cols)[idx[:, :, None], idx[:, None, :]]
    rhs = (cols.T @ g)[idx]
    with np.errstate(all="ignore"):
        try:
            coef = np.linalg.solve(gram, rhs[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            return None
        # |A c - g|^2 expanded: its rounding only orders the shortlist, checked one by one
        cost = (float(g @ g) - 2 * np.einsum("ck,ck->c", coef, rhs)
                + np.einsum("ck,ckl,cl->c", coef, gram, coef))
        slack = 1e-6 * np.max(np.abs(coef), axis=1)
        looks_valid = (np.all(coef[:, 1:] >= -slack[:, None], axis=1) & (coef[:, 0] > 0)
                       & np.isfinite(cost))
    if not looks_valid.any():
        return None
    listed = np.flatnonzero(looks_valid)
    shortlist = np.sort(listed[np.argsort(cost[listed], kind="stable")[:_SHORTLIST]])
    return _grid_each(t, g, taus, terms, [tuple(combos[c]) for c in shortlist])


def _grid_each(t: FloatArray, g: FloatArray, taus: FloatArray, terms: int,
               only: list[tuple[int, ...]] | None = None
               ) -> tuple[tuple[float, ...], FloatArray] | None:
    """One combination of ``taus`` at a time (``only``: those, as indices into the
    descending grid), linear least squares each: the first cheapest with no negative
    amplitude, or None."""
    down = taus[::-1].tolist()  # tau_1 > tau_2
    chosen = only if only is not None else itertools.combinations(range(len(down)), terms)
    best: tuple[float, tuple[float, ...], FloatArray] | None = None
    for indices in chosen:
        combo = tuple(down[i] for i in indices)
        a = _design(t, combo)
        coef = np.asarray(np.linalg.lstsq(a, g, rcond=None)[0], dtype=float)
        if np.any(coef[1:] < 0) or coef[0] <= 0:
            continue
        cost = float(np.sum((a @ coef - g) ** 2))
        if best is None or cost < best[0]:
            best = (cost, combo, coef)
    return None if best is None else (best[1], best[2])


def fit_relaxation(
    t_hold: ArrayLike, g_hold: ArrayLike, terms: int = 1, t0: float = 0.0,
    force_scale: float | ArrayLike | None = None,
) -> RelaxationFit:
    """Fit ``G(t) = G_e + sum_i G_i exp(-t/tau_i)`` (1 or 2 terms) with uncertainties, and say
    how many of its terms the data resolve.

    ``t`` (s) is measured from the hold start; ``t0`` is recorded in the result only. Every
    term count from 1 up to ``terms`` is fitted; term k is resolved when terms 1..k-1 are and
    :func:`resolution` finds no reason against it (docs/decisions/0160).

    ``force_scale`` (N/Pa, one value or one per sample): the force that is ``G = 1 Pa``
    (``K delta^1.5``). With it, a force recorded on an ADC's code lattice is fitted through
    that quantiser (:mod:`~gelrig.instrument.analysis.quantiser`, docs/decisions/0270).
    Standard errors are the heteroscedasticity-consistent sandwich's.
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
    scale = None
    if force_scale is not None:
        scale = np.broadcast_to(np.asarray(force_scale, dtype=float), t_all.shape)[ok]
    return resolve_terms((_fit_terms(t, g, k, t0, scale) for k in range(1, terms + 1)),
                         simpler_bic)


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


def _fit_terms(t: FloatArray, g: FloatArray, terms: int, t0: float,
               scale: FloatArray | None = None) -> RelaxationFit:
    """The least-squares fit with exactly ``terms`` terms, ordered longest tau first; through
    the record's quantiser when ``scale`` (N/Pa per sample) is given and the force sits on a
    code lattice."""
    start = _grid_start(*bin_means(t, g, _GRID_BINS), terms)
    # Refine on equal-count bin means: for independent noise the same estimate and, from the
    # binned residuals, the same covariance, at a fraction of the cost for long records.
    t_raw, g_raw = t, g
    t, g = bin_means(t_raw, g_raw, _REFINE_BINS)
    quantiser: DitheredQuantiser | None = None
    s_bin = np.ones_like(t)

    def smooth(p: FloatArray, tt: FloatArray) -> FloatArray:
        out = np.full_like(tt, p[0])
        for i in range(terms):
            out += p[1 + 2 * i] * np.exp(-tt / p[2 + 2 * i])
        return out

    def residual(p: FloatArray) -> FloatArray:
        model = smooth(p, t)
        if quantiser is not None:  # the codes' mean, not the signal
            model = model + quantiser.bias(model * s_bin) / s_bin
        return model - g

    def jacobian(p: FloatArray) -> FloatArray:
        cols = [np.ones_like(t)]
        for i in range(terms):
            e = np.exp(-t / p[2 + 2 * i])
            cols += [e, p[1 + 2 * i] * e * t / p[2 + 2 * i] ** 2]
        jac = np.column_stack(cols)
        if quantiser is not None:
            jac *= (1.0 + quantiser.slope(smooth(p, t) * s_bin))[:, None]
        return jac

    lower = [0.0] + [0.0, 1e-12] * terms

    def refine(p0: ArrayLike) -> Any:
        return least_squares(residual, np.asarray(p0, dtype=float), jac=jacobian,
                             bounds=(lower, np.inf), x_scale="jac")

    result = refine(start)
    lattice = find_lattice(g_raw * scale) if scale is not None else None
    if lattice is not None and scale is not None:
        s_bin = bin_means(t_raw, scale, _REFINE_BINS)[1]
        for _ in range(2):  # the noise from the fit's residual, then the fit through it
            signal = smooth(result.x, t_raw) * scale
            quantiser = DitheredQuantiser(lattice, fit_sigma(lattice, signal, g_raw * scale))
            result = refine(result.x)
    p = result.x
    err = sandwich_errors(result.jac, result.fun, np.asarray(result.active_mask) != 0)
    pairs = sorted(
        ((float(p[1 + 2 * i]), float(p[2 + 2 * i]), i) for i in range(terms)),
        key=lambda item: -item[1],
    )
    relax = tuple(RelaxationTerm(amp, tau) for amp, tau, _ in pairs)
    stderr = {"G_e": float(err[0])}
    for n, (_, _, i) in enumerate(pairs, start=1):
        stderr[f"G_{n}"] = float(err[1 + 2 * i])
        stderr[f"tau_{n}"] = float(err[2 + 2 * i])
    expected = smooth(p, t_raw)
    extra: dict[str, object] = {}
    if quantiser is not None and scale is not None:
        expected = expected + quantiser.bias(expected * scale) / scale
        extra["quantiser"] = {"step_N": quantiser.lattice.step, "phase_N": quantiser.lattice.phase,
                              "noise_N": quantiser.sigma}
    return RelaxationFit(
        g_e=float(p[0]),
        relax=relax,
        t0=t0,
        rmse=float(np.sqrt(np.mean((expected - g_raw) ** 2))),
        stderr=stderr,
        n_samples=int(t_raw.size),
        extra=extra,
    )


def sandwich_errors(jac: ArrayLike, residuals: ArrayLike, at_bound: ArrayLike) -> FloatArray:
    """Standard errors of a least-squares fit from the heteroscedasticity-consistent sandwich
    ``(J'J)^-1 J' diag(r^2) J (J'J)^-1`` (HC1: times ``n / (n - k)``); NaN where undetermined,
    as :func:`standard_errors`. Right for independent residuals of unequal variance, such as
    a quantised record's, whose spread depends on where the signal sits between two codes."""
    return np.sqrt(np.maximum(np.diag(sandwich_covariance(jac, residuals, at_bound)), 0.0))


def sandwich_covariance(jac: ArrayLike, residuals: ArrayLike, at_bound: ArrayLike
                        ) -> FloatArray:
    """The covariance behind :func:`sandwich_errors` (HC1); NaN in the rows and columns of
    the parameters it does not determine, all NaN when the fit is ill-conditioned."""
    j = np.asarray(jac, dtype=float)
    r = np.asarray(residuals, dtype=float)
    out = np.full((j.shape[1], j.shape[1]), math.nan)
    scale = np.linalg.norm(j, axis=0)
    keep = np.isfinite(scale) & (scale > 0) & ~np.asarray(at_bound, dtype=bool)
    n, k = j.shape[0], int(keep.sum())
    if not keep.any() or n <= k or not np.all(np.isfinite(r)):
        return out
    js = j[:, keep] / scale[keep]
    _, sv, vt = np.linalg.svd(js, full_matrices=False)
    if sv[-1] <= 0 or sv[0] / sv[-1] > MAX_CONDITION:
        return out
    bread = (vt.T / sv**2) @ vt
    score = js * r[:, None]
    cov = bread @ (score.T @ score) @ bread * (n / (n - k)) / np.outer(scale[keep], scale[keep])
    out[np.ix_(keep, keep)] = cov
    return out


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
    """Find the hold in a ramp-and-hold record (:func:`gelrig.instrument.analysis.hold.find_hold`;
    a retract
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
    overlap = d[start:end] if d.ndim else float(d)
    g = modulus_history(f[start:end], overlap, radius, nu)
    fit = fit_relaxation(t[start:end] - t0, g, terms=terms, t0=t0,
                         force_scale=hertz_prefactor(radius, nu) * np.asarray(overlap) ** 1.5)
    fit = with_baseline(fit, t[:start], f[:start], d[:start] if d.ndim else None,
                        hertz_prefactor(radius, nu) * float(np.mean(np.asarray(overlap))) ** 1.5)
    if overlap_stderr > 0:
        held = float(np.mean(d[start:end])) if d.ndim else float(d)
        fit = with_scale_stderr(fit, 1.5 * overlap_stderr / held)
    if delta is None:
        return fit
    return with_ramp_correction(fit, t[: start + 1], np.asarray(delta, float)[: start + 1])


def with_baseline(fit: RelaxationFit, t: ArrayLike, force: ArrayLike, delta: ArrayLike | None,
                  scale: float) -> RelaxationFit:
    """``fit`` (and its fits with fewer terms) with G_e corrected for the force the record
    reads with nothing in contact, when its force was fitted through a quantiser.

    A tare averages quantised codes: with noise below a code it is off by up to half a code,
    a constant force that G_e alone absorbs. The samples before contact (overlap below
    -:data:`BASELINE_CLEAR`) give that force by maximum likelihood through the same quantiser
    (:func:`~gelrig.instrument.analysis.quantiser.baseline_level`); ``scale`` (N/Pa) turns it
    into G. Its standard error is added to G_e's; ``extra["baseline_N"]`` keeps it.
    """
    quant = fit.extra.get("quantiser")
    if delta is None or not isinstance(quant, dict):
        return fit
    before = np.asarray(delta, dtype=float) < -BASELINE_CLEAR
    if np.count_nonzero(before) < MIN_HOLD_SAMPLES or not scale > 0:
        return fit
    lattice = Lattice(float(quant["step_N"]), float(quant["phase_N"]))
    level, err = baseline_level(np.asarray(force, dtype=float)[before], lattice,
                                float(quant["noise_N"]))
    if not (math.isfinite(level) and math.isfinite(err)):
        return fit
    return _offset(fit, level / scale, err / scale, level)


def _offset(fit: RelaxationFit, shift: float, err: float, level: float) -> RelaxationFit:
    fewer = None if fit.fewer is None else _offset(fit.fewer, shift, err, level)
    if not fit.g_e > shift:  # G_e at its bound: a slow term carries the level; left as is
        return replace(fit, fewer=fewer, extra={**fit.extra, "baseline_N": level,
                                                "baseline_applied": False})
    stderr = dict(fit.stderr)
    stderr["G_e"] = math.hypot(stderr["G_e"], err)
    return replace(fit, g_e=fit.g_e - shift, stderr=stderr, fewer=fewer,
                   extra={**fit.extra, "baseline_N": level})


def with_scale_stderr(fit: RelaxationFit, relative: float) -> RelaxationFit:
    """``fit`` (and its fits with fewer terms) with a relative uncertainty common to every
    modulus added in quadrature to G_e's and each G_i's standard error (tau's unchanged):
    the measured overlap's, ``1.5 sigma_delta / delta`` (G ~ F / delta^1.5). Kept as
    ``extra["scale_rel_stderr"]``. Called after the terms are resolved, so it changes no
    decision of the fit, only the intervals it reports (docs/decisions/0160)."""
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


def shown_amplitude(fit_dict: Mapping[str, Any], k: int, at_hold: float) -> tuple[float, str]:
    """The amplitude of term ``k`` (1-based) to show of a fit (its JSON form or ``extra``):
    the material's, corrected for relaxation during the ramp, when the fit carries it, with
    a note of the hold-start amplitude the fit itself has (``at_hold``, Pa), else that one.
    A hold's fitted G_1 is the amplitude left at its start, 0.8 % below the material's on
    the paper's ramp: shown bare beside a material's G_1 it reads as a bias."""
    corrected = fit_dict.get("relax_ramp_corrected")
    if isinstance(corrected, Sequence) and len(corrected) >= k and \
            isinstance(corrected[k - 1], Mapping):
        g = float(corrected[k - 1].get("G", math.nan))
        if math.isfinite(g):
            return g, f" (ramp-corrected; {at_hold:.0f} at the hold's start)"
    return at_hold, ""


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
    #: standard error of ``baseline`` (N), and the correlation of the two estimates' errors
    baseline_stderr: float = math.nan
    correlation: float = math.nan


def loading_law(t: ArrayLike, material: Material) -> Callable[[FloatArray], FloatArray]:
    """The force's shape along a loading record at times ``t`` (s): by the hereditary
    integral (physics.md, section 1) a contact that only grows from none carries
    ``F = K (G_e x + sum G_i h_i)``, ``x = d^1.5``, ``h_i = int exp(-(t - s)/tau_i) dx(s)``.
    Returns ``d -> x + sum (G_i/G_e) h_i`` for overlaps ``d`` (m) at those times: the
    relaxing law of ``material`` that :func:`estimate_first_touch` can fit exactly, where
    ``1 + c d`` is a first-order stand-in."""
    ts = np.asarray(t, dtype=float)
    dt = np.diff(ts, prepend=ts[0] if ts.size else 0.0)
    terms = [(term.g / material.g_e, term.tau) for term in material.relax]

    def law(d: FloatArray) -> FloatArray:
        x = d * np.sqrt(d)
        out = x.copy()
        for ratio, tau in terms:
            out += ratio * hereditary(dt, x, tau)
        return np.asarray(out, dtype=float)

    return law


def _start_line(x: FloatArray, y: FloatArray) -> tuple[float, float]:
    """The line through ``F^(2/3)`` against position that starts the first-touch fit: least
    squares over the points within 5 robust sigma of a repeated-medians line. A noise sample
    above 0.3 of the peak far before contact (a noisy cell over millimetres of probing: 0.5 mN
    against a 5 mN threshold) would otherwise tilt the line and the fit would not find the
    touch."""
    step = max(1, x.size // 400)  # the repeated medians cost the square of the points
    slope = siegel_slope(y[::step], x[::step])
    intercept = float(np.median(y - slope * x))
    off = y - (slope * x + intercept)
    spread = 1.4826 * float(np.median(np.abs(off)))
    keep = np.abs(off) <= 5 * spread if spread > 0 else np.ones(x.size, dtype=bool)
    if np.unique(x[keep]).size < 3:
        keep = np.ones(x.size, dtype=bool)
    line = np.polyfit(x[keep], y[keep], 1)
    return float(line[0]), float(line[1])


def estimate_first_touch(position: ArrayLike, force: ArrayLike, relaxing: bool = False,
                         quantised: bool = False,
                         law: Callable[[FloatArray], FloatArray] | None = None) -> FirstTouch:
    """Where a plate first touched a sphere, from its force-displacement approach curve.

    Fits ``F = A d^1.5 (1 + c d) + b`` with ``d = max(z - z0, 0)`` by least squares, z0 free
    (docs/decisions/0160). Hertzian force is still tiny tens of micrometres past touch, so a
    threshold crossing overestimates z0; the fit uses the whole curve. Start values come from
    a line through ``F^(2/3)`` of the upper half. ``c`` is fitted only when ``relaxing``: on a
    slow ramp (tens of seconds) the material relaxes as the overlap grows, which a pure
    d^1.5 would absorb into z0 (0.9 um early on the paper's shell); on a fast probe c = 0.

    ``quantised``: when the force sits on an ADC's code lattice, refit through that quantiser
    (its noise read off the first fit's residuals, docs/decisions/0270): near touch the force
    is below one code, where the codes' mean is not the force, and a plain fit puts z0 early
    by several times its standard error when the noise is below a code.

    ``law``: the force's shape as a function of the overlap at these samples (e.g.
    :func:`loading_law` from a fit of the material), fitted as ``F = A law(d) + b`` in place
    of ``d^1.5 (1 + c d)``: on a ramp about as long as the material's relaxation time the
    first-order softening leaves z0 early by about a standard error (ADR 0375).
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
    slope, intercept = _start_line(z[upper], np.cbrt(f[upper]) ** 2)
    if slope <= 0:
        raise ConfigError("approach", slope, "the force does not rise with the travel")
    z0_guess = -intercept / slope
    reach = max(float(np.max(z)) - z0_guess, 1e-9)  # travel past touch, for the scales

    if law is not None:
        relaxing = False
        shape = law

        def residual(p: FloatArray) -> FloatArray:
            return p[1] * shape(np.maximum(z - p[0], 0.0)) + p[2] - f

        # the amplitude and baseline at the guessed touch, by linear least squares
        basis = np.column_stack([shape(np.maximum(z - z0_guess, 0.0)), np.ones(z.size)])
        amp0 = float(np.linalg.lstsq(basis, f, rcond=None)[0][0])
        amp0 = amp0 if amp0 > 0 else slope**1.5
    else:
        amp0 = slope**1.5

        def residual(p: FloatArray) -> FloatArray:
            d = np.maximum(z - p[0], 0.0)
            soft = 1.0 + p[3] * d if relaxing else 1.0
            return p[1] * d * np.sqrt(d) * soft + p[2] - f

    start = [z0_guess, amp0, 0.0]
    scale = [1e-5, amp0, max(top, 1e-9) * 1e-2]
    bounds = ([-np.inf] * 3, [np.inf] * 3)
    if relaxing:  # a gentle first-order softening, |c d| < 0.5 over the curve
        start.append(0.0)
        scale.append(0.01 / reach)
        bounds = ([*bounds[0], -0.5 / reach], [*bounds[1], 0.5 / reach])
    result = least_squares(residual, start, bounds=bounds, x_scale=scale)
    lattice = find_lattice(f) if quantised else None
    cov = _touch_covariance(result.jac, result.fun)
    if lattice is not None:
        plain = residual
        quantiser = DitheredQuantiser(lattice, fit_sigma(lattice, plain(result.x) + f, f))

        def residual(p: FloatArray) -> FloatArray:
            model = plain(p) + f
            return model + quantiser.bias(model) - f

        result = least_squares(residual, result.x, bounds=bounds, x_scale=scale)
        cov = sandwich_covariance(result.jac, result.fun, np.zeros(result.x.size, bool))
    z0, amp, base = (float(v) for v in result.x[:3])
    err, base_err = (math.sqrt(max(float(cov[i, i]), 0.0)) if math.isfinite(cov[i, i])
                     else math.nan for i in (0, 2))
    corr = float(cov[0, 2]) / (err * base_err) if err > 0 and base_err > 0 else math.nan
    return FirstTouch(z0, amp, base, float(np.sqrt(np.mean(result.fun**2))),
                      int(np.count_nonzero(z > z0)), float(result.x[3]) if relaxing else 0.0,
                      err, base_err, corr)


def _touch_covariance(jac: FloatArray, residuals: FloatArray) -> FloatArray:
    """Covariance of a least-squares fit's parameters from its Jacobian and residuals (white
    noise); all NaN when it is singular."""
    n, k = jac.shape
    out = np.full((k, k), math.nan)
    norms = np.linalg.norm(jac, axis=0)
    if n <= k or not np.all(np.isfinite(jac)) or not np.all(norms > 0):
        return out
    scaled = jac / norms  # columns of unit length: the conditioning is the fit's, not units'
    normal = scaled.T @ scaled
    if np.linalg.cond(normal) > 1e12:
        return out
    variance = float(np.sum(residuals**2)) / (n - k)
    return np.asarray(variance * np.linalg.inv(normal) / np.outer(norms, norms), dtype=float)
