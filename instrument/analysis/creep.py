"""A creep hold (the force held by feedback, the overlap creeping) fitted with the model.

What is fitted, and why: under the contact model (physics.md section 1) the force is linear
in ``x = delta^1.5`` through the hereditary integral, so while the contact only grows
``x(t) = (1/K) int J(t - s) dF(s)`` (Lee and Radok), ``J`` the creep compliance of the
relaxation modulus ``G(t)``. For the one-term Prony ``G = G_e + G_1 exp(-t/tau)`` it is
``J(t) = J_e - dJ exp(-t/tau_c)`` with ``J_e = 1/G_e``, ``dJ = 1/G_e - 1/G_0``,
``G_0 = G_e + G_1`` and the retardation time ``tau_c = tau G_0 / G_e``. Hence, for any force
history, exactly

    x(t) = (J_e F(t) - dJ H(t)) / K,    H(t) = int exp(-(t - s)/tau_c) dF(s),

which is what is fitted to the hold's overlap, the recorded force (the feedback holds it
only on average) in F and H: linear in J_e and dJ, so tau_c comes from a log grid and all
three are then refined together. With the loading recorded (the force from about 0) H runs
from it and G_e, G_1, tau_1 and tau_c all follow; without it H runs from the hold's start and
the state the loading left is a free ``- C exp(-t/tau_c)``: G_e and tau_c stay determined, dJ
only by the force's wander (G_1, tau_1 are then usually "not resolved"). Only samples with the
plate still between two corrections enter (the stage's position is interpolated between its
reports while it moves, off by more than the force's noise); they are averaged into bins of
:data:`BIN_S`, and the standard errors are autocorrelation-consistent (Newey-West: the
feedback's wander leaves the residuals correlated over several bins), carried to G_e, G_1 and
tau_1 by the delta method. Treating the force's wander as elastic instead (``x = F J_e / K -
B exp(-t/tau_c)``) biased tau_c and G_1 by several standard errors on the simulated rig.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from gelrig.instrument.analysis.quantiser import DitheredQuantiser, find_lattice, fit_sigma
from gelrig.instrument.analysis.relaxation import (
    MAX_CONDITION,
    MAX_RELATIVE_ERROR,
    MIN_HOLD_SAMPLES,
)
from gelrig.instrument.core.binning import bin_means
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import FloatArray, hereditary, hertz_prefactor

#: The fit averages the hold into bins of about this length (s): the feedback's ripple (a
#: correction every period) averages out within one, so the bins' residuals are near white.
BIN_S = 2.0
_MAX_BINS = 2000


@dataclass(frozen=True)
class CreepFit:
    """A creep hold's fit (Pa, s; t from the hold start): ``values`` and ``stderr`` by name
    (``G_e``, ``tau_c``, and with the loading ``G_1``, ``tau_1``), the held ``force`` (N),
    the creep curve's ``t``, ``x`` = delta^1.5 and the model at ``t``. ``not_resolved`` says
    why the fit is not a result ("" when it is); ``partial`` why G_1, tau_1 are not."""

    force: float
    values: dict[str, float]
    stderr: dict[str, float]
    rmse: float
    n_samples: int
    t: FloatArray
    x: FloatArray
    x_model: FloatArray
    not_resolved: str = ""
    partial: str = ""
    extra: dict[str, object] = field(default_factory=dict)

    @property
    def warnings(self) -> list[str]:
        """Where the recipe is known to be weak: a hold shorter than the fitted tau_c."""
        span = float(self.t[-1] - self.t[0]) if self.t.size > 1 else 0.0
        tau_c = self.values.get("tau_c", math.nan)
        if self.is_resolved and math.isfinite(tau_c) and span < tau_c:
            return [f"the hold ({span:.0f} s) is shorter than the fitted tau_c ({tau_c:.0f} s): "
                    "a hold cannot resolve a time constant longer than itself; hold for "
                    "several tau_c"]
        return []

    @property
    def is_resolved(self) -> bool:
        """Whether G_e and tau_c are a result."""
        return not self.not_resolved

    def value(self, name: str) -> float:
        """A resolved value, NaN when it is not a result."""
        if not self.is_resolved or (name in ("G_1", "tau_1") and self.partial):
            return math.nan
        return self.values.get(name, math.nan)


def _fit(residual: Callable[[FloatArray], FloatArray], p0: list[float], lower: list[float]
         ) -> tuple[FloatArray, list[FloatArray], FloatArray]:
    """Least squares from ``p0``: the parameters, two covariances (from a central-difference
    Jacobian; NaN when singular), and the residuals. The covariances: the sandwich of
    independent bins (HC1) and the Newey-West one (the feedback may leave the residuals
    correlated over several bins); with few bins the latter's lagged terms can also shrink it
    (tau's error / s.e. 1.20 over 40 seeds of the rig, 0.96 with HC1), so the caller takes
    the larger error of each value (ADR 0375)."""
    result = least_squares(residual, np.asarray(p0, dtype=float), bounds=(lower, np.inf),
                           x_scale="jac")
    p = np.asarray(result.x, dtype=float)
    fun = np.asarray(result.fun, dtype=float)
    jac = np.empty((fun.size, p.size))
    for i in range(p.size):
        h = 1e-5 * max(abs(p[i]), 1e-30)
        up, down = p.copy(), p.copy()
        up[i] += h
        down[i] -= h
        jac[:, i] = (residual(up) - residual(down)) / (2 * h)
    n, m = jac.shape
    scale = np.linalg.norm(jac, axis=0)
    cov = np.full((m, m), math.nan)
    white = cov
    if n > m and np.all(scale > 0) and np.all(np.isfinite(jac)):
        js = jac / scale
        sv = np.linalg.svd(js, compute_uv=False)
        if sv[-1] > 0 and sv[0] / sv[-1] < MAX_CONDITION:
            bread = np.linalg.inv(js.T @ js)
            score = js * fun[:, None]
            meat = score.T @ score
            white = bread @ meat @ bread * (n / (n - m)) / np.outer(scale, scale)
            lags = max(1, round(n ** (1 / 3)))  # Newey-West: the feedback's slow wander
            for lag in range(1, lags + 1):
                gamma = score[lag:].T @ score[:-lag]
                meat += (1 - lag / (lags + 1)) * (gamma + gamma.T)
            cov = bread @ meat @ bread * (n / (n - m)) / np.outer(scale, scale)
    return p, [white, cov], fun


#: The window (s) of the running mean whose quantiser bias is taken off the force: long enough
#: to average the noise over the codes, short against the feedback's corrections.
DEQUANTISE_S = 0.3


def _dequantised(t: FloatArray, force: FloatArray) -> FloatArray:
    """The force with the ADC's expected error taken off where it is slow: below one code of
    noise (0.3 mN on the USB-6001 at the rig's range) the codes' mean is not the force but
    ``x + b(x)`` (ADR 0270), and a creep holds the force near one level for its whole hold,
    so ``b`` stays put and reads as a change of modulus (tau_1 0.5 % short at 0.1 mN). The
    noise is read off the record (``fit_sigma``), ``x`` solved from the running mean by
    Newton steps on ``x + b(x) = mean``; where the mean moves by a code within the window
    (the loading) the codes dither themselves and nothing is taken off. Unquantised records
    are returned as they are."""
    lattice = find_lattice(force)
    if lattice is None or force.size < 8:
        return force
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    width = max(3, round(DEQUANTISE_S / dt)) if dt > 0 else 3
    kernel = np.ones(width)
    mean = (np.convolve(force, kernel, mode="same")
            / np.convolve(np.ones(force.size), kernel, mode="same"))
    quantiser = DitheredQuantiser(lattice, fit_sigma(lattice, mean, force))
    x = mean.copy()
    for _ in range(4):
        x = x - (x + quantiser.bias(x) - mean) / (1.0 + quantiser.slope(x))
    slow = np.abs(np.gradient(mean, t)) * DEQUANTISE_S < lattice.step
    return np.asarray(force + np.where(slow, x - mean, 0.0), dtype=float)


def _input_errors(t: FloatArray, delta: FloatArray, force: FloatArray, start: int,
                  radius: float, nu: float, loading: int | None, inputs: Uncertain
                  ) -> dict[str, float]:
    """Each value's standard error from the errors of its inputs that the fit takes as
    exact: first touch (moving the whole overlap) and the force's baseline (the tare's
    remainder, moving the whole force), with their correlation (from the touch's fit).
    The sensitivities are refits with each input moved by its standard error: not a common
    scale, since over a creep the overlap grows and a moved touch changes the curve's shape
    too (G_1 moves about twice as far as G_e, relatively; ADR 0375)."""
    def moved(sigma: float, on_touch: bool) -> dict[str, float]:
        """Half the difference of two refits with one input moved by -+ sigma."""
        if not (sigma > 0 and math.isfinite(sigma)):
            return dict.fromkeys(_NAMES, 0.0)
        ends = [fit_creep(t, delta - s if on_touch else delta, force if on_touch else force - s,
                          start, radius, nu, loading).values for s in (sigma, -sigma)]
        return {n: (ends[0][n] - ends[1][n]) / 2 for n in _NAMES}

    try:
        a, b = moved(inputs.touch_stderr, True), moved(inputs.baseline_stderr, False)
    except ConfigError:
        return {}
    rho = inputs.correlation if math.isfinite(inputs.correlation) else 0.0
    out = {}
    for n in _NAMES:
        var = a[n] ** 2 + b[n] ** 2 + 2 * rho * a[n] * b[n]
        if math.isfinite(var):
            out[n] = math.sqrt(max(var, 0.0))
    return out


@dataclass(frozen=True)
class Uncertain:
    """What the overlap and force of a creep fit were measured with, beyond the hold's own
    noise: first touch's standard error (m), the force baseline's (N) and the correlation of
    the two (from the ramp's first-touch fit; 0 when they come from elsewhere)."""

    touch_stderr: float = 0.0
    baseline_stderr: float = 0.0
    correlation: float = 0.0


_NAMES = ("G_e", "G_1", "tau_1", "tau_c")


def fit_creep(
    t: ArrayLike, delta: ArrayLike, force: ArrayLike, start: int, radius: float,
    nu: float = 0.5, loading: int | None = None, overlap_stderr: float = 0.0,
    inputs: Uncertain | None = None,
) -> CreepFit:
    """Fit the creep of the hold that runs from sample ``start`` to the end of the record:
    ``t`` (s), the overlap ``delta`` (m) and the ``force`` (N); ``radius`` (m) the sphere's;
    ``loading`` the sample where the loading begins (force about 0), None when the record does
    not show it. ``overlap_stderr`` (m): the overlap's (its first touch's) standard error;
    ``inputs`` in its place also the force baseline's, as the ramp's touch fit measured them
    (the force is then already less that baseline). Both are carried to every value by
    refitting with the inputs moved (ADR 0375; a hold's moduli take ``1.5 sigma / delta``,
    docs/decisions/0160). Raises ConfigError when there is nothing to fit."""
    t_all = np.asarray(t, dtype=float)
    d_all = np.asarray(delta, dtype=float)
    f_raw = np.asarray(force, dtype=float)
    first = start if loading is None else loading
    f_all = f_raw.copy()
    if np.all(np.isfinite(f_raw[first:])) and np.all(np.isfinite(t_all[first:])):
        f_all[first:] = _dequantised(t_all[first:], f_raw[first:])
    tt, d, f = t_all[start:], d_all[start:], f_all[start:]
    ok = np.isfinite(tt) & np.isfinite(d) & np.isfinite(f) & (d > 0)
    if np.count_nonzero(ok) < MIN_HOLD_SAMPLES or not ok.all():
        raise ConfigError("creep", int(np.count_nonzero(ok)),
                          f"need at least {MIN_HOLD_SAMPLES} samples, all in contact, to fit")
    # the plate between corrections: there the position is the encoder's, not interpolated
    # between polls while the stage moves (off by far more than the force's noise)
    still = np.r_[False, np.diff(d) == 0] & np.r_[np.diff(d) == 0, False]
    if np.count_nonzero(still) >= max(MIN_HOLD_SAMPLES, d.size // 4):
        tt, d, f = tt[still], d[still], f[still]
    else:
        still = np.ones(d.size, dtype=bool)
    if not np.all(np.isfinite(f_all[first:start])):
        raise ConfigError("creep", "loading", "the force is not finite over the loading")
    held = float(np.mean(f))
    k = hertz_prefactor(radius, nu)
    t_rel = tt - tt[0]
    span = float(t_rel[-1]) if t_rel.size > 1 else 1.0
    bins = int(min(_MAX_BINS, max(MIN_HOLD_SAMPLES, span / BIN_S)))
    tb, xb = bin_means(t_rel, d**1.5, bins)
    fb = bin_means(t_rel, f, bins)[1]
    where = (np.flatnonzero(still) if np.count_nonzero(still) >= max(
        MIN_HOLD_SAMPLES, still.size // 4) else np.arange(still.size)) + (start - first)
    dt = np.diff(t_all[first:], prepend=t_all[first])
    f_hist = f_all[first:]
    free = loading is None  # the loading's state is then a free amplitude C
    x_prev = float(f_all[start]) if free else 0.0
    unit = float(np.mean(xb)) * 1e-4  # residuals of order 1: the solver's tolerances

    def history(tau_c: float) -> FloatArray:
        h = hereditary(dt, f_hist, tau_c, x_prev=x_prev)[where]
        return bin_means(t_rel, h, bins)[1]

    def design(tau_c: float) -> FloatArray:
        cols = [fb / k, -history(tau_c) / k]
        if free:
            cols.append(-np.exp(-tb / tau_c))
        return np.column_stack(cols)

    best: tuple[float, float, FloatArray] | None = None
    for tau_c in np.geomspace(max(span * 1e-3, 1e-3), 30 * span, 60):
        a = design(float(tau_c))
        coef = np.linalg.lstsq(a, xb, rcond=None)[0]
        cost = float(np.sum((a @ coef - xb) ** 2))
        if coef[0] > 0 and (best is None or cost < best[0]):
            best = (cost, float(tau_c), np.asarray(coef, dtype=float))
    if best is None:
        raise ConfigError("creep", held, "the overlap does not follow a creep curve")
    _, tau0, coef = best

    def residual(p: FloatArray) -> FloatArray:
        return np.asarray((design(float(p[-1])) @ p[:-1] - xb) / unit, dtype=float)

    p, covs, res = _fit(residual, [*map(float, coef), tau0],
                       [1e-12, -np.inf] + ([-np.inf] if free else []) + [1e-6])
    res = res * unit

    def derived(q: FloatArray) -> FloatArray:
        """(G_e, G_1, tau_1, tau_c) from (J_e, dJ, [C,] tau_c)."""
        g_e = 1 / q[0]
        g_0 = 1 / (q[0] - q[1]) if q[0] > q[1] else math.nan
        return np.array([g_e, g_0 - g_e, q[-1] * g_e / g_0, q[-1]])

    values_v = derived(p)
    jac = np.empty((4, p.size))
    for i in range(p.size):  # the delta method through the fit's covariance
        h = 1e-6 * max(abs(float(p[i])), 1e-30)
        up, down = p.copy(), p.copy()
        up[i] += h
        down[i] -= h
        jac[:, i] = (derived(up) - derived(down)) / (2 * h)
    errs = np.fmax(*(np.sqrt(np.maximum(np.diag(jac @ c @ jac.T), 0.0)) for c in covs))
    values = {n: float(v) for n, v in zip(_NAMES, values_v, strict=True)}
    stderr = {n: float(e) for n, e in zip(_NAMES, errs, strict=True)}
    values.update(J_e=float(p[0]), dJ=float(p[1]))
    tau_c = float(p[-1])
    given = inputs if inputs is not None else Uncertain(overlap_stderr)
    if given.touch_stderr > 0 or given.baseline_stderr > 0:  # carried through the whole fit
        for name, err in _input_errors(t_all, d_all, f_all, start, radius, nu, loading,
                                       given).items():
            stderr[name] = math.hypot(stderr[name], err)

    def reason(check: tuple[str, ...]) -> str:
        for name in check:
            value, err = values[name], stderr[name]
            rel = err / abs(value) if value and math.isfinite(value) else math.inf
            if not math.isfinite(rel):
                return f"{name} undetermined (covariance singular, or no compliance step)"
            if rel > MAX_RELATIVE_ERROR:
                return (f"{name} has a relative standard error of {rel:.3g} "
                        f"(> {MAX_RELATIVE_ERROR:g})")
        return ""

    why = reason(("G_e", "tau_c"))
    partial = "the creep is not resolved" if why else reason(("G_1", "tau_1"))
    if partial and free and not why:
        partial += " (the loading before the hold is not recorded)"
    return CreepFit(held, values, stderr, float(np.sqrt(np.mean(res**2))), int(tt.size),
                    tb, xb, res + xb, why, partial, {"loading_recorded": not free})
