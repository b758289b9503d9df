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
from dataclasses import dataclass, field

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
    force: ArrayLike, delta_hold: float, radius: float, nu: float = 0.5
) -> FloatArray:
    """Back-calculated shear modulus G(t) = F / (K delta_hold^1.5) in Pa."""
    if not delta_hold > 0:
        raise ConfigError("depth", delta_hold, "hold overlap must be > 0 m")
    k = hertz_prefactor(radius, nu)
    return np.asarray(force, dtype=float) / (k * delta_hold**1.5)


@dataclass(frozen=True)
class RelaxationFit:
    """Result of a Prony fit of G(t) over a hold (Pa, s; t measured from the hold start)."""

    g_e: float
    relax: tuple[RelaxationTerm, ...]
    t0: float
    rmse: float
    stderr: dict[str, float]
    n_samples: int
    extra: dict[str, object] = field(default_factory=dict)

    def model(self, t: ArrayLike) -> FloatArray:
        """G(t) of the fitted series, t from the hold start (s)."""
        return Material(self.g_e, self.relax).modulus(t)

    def as_dict(self) -> dict[str, object]:
        """The JSON form of the CLI contract (``gelrig fit relaxation``)."""
        out: dict[str, object] = {
            "G_e": self.g_e,
            "relax": [{"G": term.g, "tau": term.tau} for term in self.relax],
            "t0_s": self.t0,
            "rmse": self.rmse,
            "stderr": self.stderr,
        }
        out.update(self.extra)
        return out


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
    """Fit ``G(t) = G_e + sum_i G_i exp(-t/tau_i)`` (1 or 2 terms) with uncertainties.

    ``t`` (s) is measured from the hold start; ``t0`` is recorded in the result only.
    """
    if terms not in (1, 2):
        raise ConfigError("terms", terms, "allowed: 1 or 2")
    t_all = np.asarray(t_hold, dtype=float)
    g_all = np.asarray(g_hold, dtype=float)
    ok = np.isfinite(t_all) & np.isfinite(g_all)
    t, g = t_all[ok], g_all[ok]
    if t.size < MIN_HOLD_SAMPLES:
        raise ConfigError("hold", t.size, f"need at least {MIN_HOLD_SAMPLES} samples to fit")
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
    rss = float(np.sum(result.fun**2))
    jac = result.jac
    try:
        cov = np.linalg.inv(jac.T @ jac) * rss / dof
        err = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        err = np.full(p.size, math.inf)
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


def fit_hold(
    time: ArrayLike,
    force: ArrayLike,
    radius: float,
    depth: float,
    nu: float = 0.5,
    terms: int = 1,
    delta: ArrayLike | None = None,
) -> RelaxationFit:
    """Find the hold in a ramp-and-hold record (:func:`instrument.hold.find_hold`; a retract
    after it is left out), back-calculate G(t) and fit it.

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
    g = modulus_history(f[start:end], depth, radius, nu)
    fit = fit_relaxation(t[start:end] - t0, g, terms=terms, t0=t0)
    if delta is None:
        return fit
    corrected = ramp_corrected(fit, t[: start + 1], np.asarray(delta, float)[: start + 1])
    return RelaxationFit(
        fit.g_e,
        fit.relax,
        fit.t0,
        fit.rmse,
        fit.stderr,
        fit.n_samples,
        {"relax_ramp_corrected": [{"G": r.g, "tau": r.tau} for r in corrected]},
    )


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
    """First-touch estimate from an approach curve: position (m), Hertz amplitude, residual."""

    position: float
    amplitude: float
    baseline: float
    rmse: float
    n_contact: int


def estimate_first_touch(position: ArrayLike, force: ArrayLike) -> FirstTouch:
    """Where a plate first touched a sphere, from its force-displacement approach curve.

    Fits ``F = A max(z - z0, 0)^1.5 + b`` by least squares. Hertzian force is still tiny tens
    of micrometres past touch, so a threshold crossing overestimates z0; the fit uses the
    whole curve. Start values come from a line through ``F^(2/3)`` of the upper half.
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

    def residual(p: FloatArray) -> FloatArray:
        d = np.maximum(z - p[0], 0.0)
        return p[1] * d * np.sqrt(d) + p[2] - f

    result = least_squares(residual, [z0_guess, slope**1.5, 0.0],
                           x_scale=[1e-5, slope**1.5, max(top, 1e-9) * 1e-2])
    z0, amp, base = (float(v) for v in result.x)
    return FirstTouch(z0, amp, base, float(np.sqrt(np.mean(result.fun**2))),
                      int(np.count_nonzero(z > z0)))
