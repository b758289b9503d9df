"""A relaxation fit kept up to date while a hold runs, and the rule that may end the hold early.

Samples of G(t) arrive in blocks; each is reduced at once into fixed-width time bins (count, sum
of t, sum of G, sum of G^2), so a refit costs the same at the end of a 3000 s hold at 1 kHz as
at its start: a weighted least-squares fit on at most :data:`MAX_BINS` bin means. The weights
are the counts, so estimate and covariance are those of the raw samples (white noise); the raw
residual sum of squares is rebuilt from the bins (between-bin part from the fit, within-bin
part from the sums), so the BIC, and hence the resolved-terms rule of
``gelrig.instrument.analysis.relaxation.resolution`` (docs/decisions/0160), is the same as offline.

A refit also forecasts each time constant's relative standard error at the planned end of the
hold: the Fisher information of the current model sampled at the acquisition rate up to then,
with the current noise estimate (docs/decisions/0180).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from gelrig.instrument.analysis.relaxation import (
    MAX_CONDITION,
    MIN_HOLD_SAMPLES,
    RelaxationFit,
    _grid_start,
    resolve_terms,
    standard_errors,
)
from gelrig.instrument.core.binning import bin_means
from gelrig.instrument.physics.contact import FloatArray, RelaxationTerm

#: Bins of the whole planned hold (the bin width is planned hold / this, at least a sample).
MAX_BINS = 3000
#: Refit when the hold has grown by this fraction since the last refit ...
CADENCE = 0.05
#: ... but not more often than this (s of hold) ...
MIN_INTERVAL = 5.0
#: ... and not before this many bins hold data.
MIN_BINS = 30
#: Bins the grid search for starting values averages into ...
_GRID_BINS = 200
#: ... and it runs on every this many refits (the others start from the last refit only).
GRID_EVERY = 4
#: Model evaluations a refit's least squares may take (a warm start needs a few; a term
#: the data do not yet support can wander for hundreds, and the next refit tries again).
MAX_EVALUATIONS = 60
#: Points of the bin means and of the fitted curve a state carries for drawing.
DRAW_POINTS = 300
#: Points the planned-end forecast samples the model at.
_FORECAST_POINTS = 400


@dataclass(frozen=True)
class LiveFitState:
    """One refit during a hold: the reported (resolved) fit's parameters and standard errors
    (Pa, s; NaN undetermined), terms resolved and why not more, each time constant's relative
    standard error now and forecast at the planned end (of the fit with the terms asked)."""

    elapsed: float
    planned: float
    g_e: float
    relax: tuple[RelaxationTerm, ...]
    stderr: dict[str, float]
    terms_resolved: int
    not_resolved: str
    n_samples: int
    relative: dict[str, float]
    forecast: dict[str, float]
    #: the fit with every term asked (for the band and the forecast), as ``relax``/``stderr``
    full_relax: tuple[RelaxationTerm, ...] = ()
    full_stderr: dict[str, float] = field(default_factory=dict)
    full_g_e: float = math.nan
    #: for drawing: G(t) bin means (at most :data:`DRAW_POINTS`; s, Pa) ...
    data: tuple[FloatArray, FloatArray] = (np.empty(0), np.empty(0))
    #: ... and the reported fit on a grid over the hold with its standard deviation (s, Pa,
    #: Pa; NaN where the covariance does not determine it)
    curve: tuple[FloatArray, FloatArray, FloatArray] = (np.empty(0), np.empty(0), np.empty(0))
    #: the residuals' rms (Pa), the noise the fit's errors take as white
    noise: float = math.nan

    @property
    def tau(self) -> float:
        """The longest time constant of the reported fit (s)."""
        return self.relax[0].tau if self.relax else math.nan

    @property
    def tau_relative(self) -> float:
        """Its relative standard error (NaN undetermined)."""
        return self.relative.get("tau_1", math.nan)

    def as_dict(self) -> dict[str, Any]:
        """JSON form (NaN as null): what the step's results and run.json keep."""
        def num(v: float) -> float | None:
            return v if math.isfinite(v) else None
        return {
            "elapsed_s": self.elapsed,
            "G_e": self.g_e,
            "relax": [{"G": r.g, "tau": r.tau} for r in self.relax],
            "stderr": {k: num(v) for k, v in self.stderr.items()},
            "terms_resolved": self.terms_resolved,
            "not_resolved": self.not_resolved,
            "n_samples": self.n_samples,
            "relative": {k: num(v) for k, v in self.relative.items()},
            "forecast": {k: num(v) for k, v in self.forecast.items()},
        }


def model(g_e: float, relax: tuple[RelaxationTerm, ...], t: ArrayLike) -> FloatArray:
    """``G_e + sum G_i exp(-t/tau_i)`` (Pa) at ``t`` (s from the hold start)."""
    tt = np.asarray(t, dtype=float)
    out = np.full_like(tt, g_e)
    for r in relax:
        out += r.g * np.exp(-tt / r.tau)
    return out


def _jacobian(p: FloatArray, t: FloatArray, terms: int) -> FloatArray:
    cols = [np.ones_like(t)]
    for i in range(terms):
        e = np.exp(-t / p[2 + 2 * i])
        cols += [e, p[1 + 2 * i] * e * t / p[2 + 2 * i] ** 2]
    return np.column_stack(cols)


def _value(p: FloatArray, t: FloatArray, terms: int) -> FloatArray:
    out = np.full_like(t, p[0])
    for i in range(terms):
        out += p[1 + 2 * i] * np.exp(-t / p[2 + 2 * i])
    return out


class LiveFit:
    """Bins G(t) samples of a hold as they arrive and refits 1..``terms`` relaxation terms.

    ``planned`` (s) is the planned end of the hold (the forecast's horizon; the maximum of an
    adaptive hold), ``rate`` (Hz) the sample rate.
    """

    def __init__(self, terms: int, planned: float, rate: float, cadence: float = CADENCE,
                 min_interval: float = MIN_INTERVAL, inflation: float = 1.0):
        #: what the standard errors, forecasts and band are multiplied by: the rig's
        #: correlated noise (:func:`correlated_inflation`), 1 for white noise
        self.inflation = inflation
        self.terms = terms
        self.planned = planned
        self.rate = rate
        self.cadence = cadence
        self.min_interval = min_interval
        self.width = max(1.0 / rate, planned / MAX_BINS)
        size = math.ceil(planned / self.width) + 2
        self._n = np.zeros(size)
        self._st = np.zeros(size)
        self._sg = np.zeros(size)
        self._sg2 = np.zeros(size)
        self._next = 0.0
        self._last: dict[int, FloatArray] = {}  # warm starts by term count
        self.history: list[LiveFitState] = []

    @property
    def samples(self) -> int:
        return int(self._n.sum())

    def add(self, t: ArrayLike, g: ArrayLike) -> None:
        """Bin samples ``g`` (Pa) at ``t`` (s from the hold start); non-finite ones are left
        out."""
        tt = np.asarray(t, dtype=float)
        gg = np.asarray(g, dtype=float)
        ok = np.isfinite(tt) & np.isfinite(gg) & (tt >= 0)
        tt, gg = tt[ok], gg[ok]
        if not tt.size:
            return
        idx = (tt / self.width).astype(int)
        need = int(idx.max()) + 1
        if need > self._n.size:  # the hold ran past its plan: grow
            grow = max(need, 2 * self._n.size) - self._n.size
            for name in ("_n", "_st", "_sg", "_sg2"):
                setattr(self, name, np.concatenate((getattr(self, name), np.zeros(grow))))
        size = self._n.size
        self._n += np.bincount(idx, minlength=size)
        self._st += np.bincount(idx, tt, minlength=size)
        self._sg += np.bincount(idx, gg, minlength=size)
        self._sg2 += np.bincount(idx, gg * gg, minlength=size)

    def due(self, elapsed: float) -> bool:
        """Whether a refit is due at ``elapsed`` s of hold (every :data:`CADENCE` of the
        elapsed hold, at least :data:`MIN_INTERVAL` apart, once :data:`MIN_BINS` bins hold
        data)."""
        return elapsed >= self._next and int(np.count_nonzero(self._n)) >= MIN_BINS

    def bins(self) -> tuple[FloatArray, FloatArray, FloatArray, float]:
        """Bin mean times and G, their counts, and the within-bin sum of squares."""
        keep = self._n > 0
        n = self._n[keep]
        tb, gb = self._st[keep] / n, self._sg[keep] / n
        within = float(np.sum(np.maximum(self._sg2[keep] - n * gb * gb, 0.0)))
        return tb, gb, n, within

    def refit(self, elapsed: float) -> LiveFitState | None:
        """Refit on everything so far; None while there are too few samples."""
        self._next = max(elapsed * (1 + self.cadence), elapsed + self.min_interval)
        tb, gb, n, within = self.bins()
        total = int(n.sum())
        if total < MIN_HOLD_SAMPLES or tb.size < 2 * (1 + 2 * self.terms):
            return None
        grid = len(self.history) % GRID_EVERY == 0
        fit = fit_binned(tb, gb, n, within, self.terms, self._last, grid=grid)
        state = self._state(fit, elapsed, tb, gb, n)
        self.history.append(state)
        return state

    def _state(self, fit: RelaxationFit, elapsed: float, tb: FloatArray, gb: FloatArray,
               n: FloatArray) -> LiveFitState:
        shown = fit.resolved
        k = self.inflation
        stderr = {name: k * v for name, v in shown.stderr.items()}
        relative = {f"tau_{i}": stderr.get(f"tau_{i}", math.nan) / r.tau
                    for i, r in enumerate(shown.relax, 1)}
        noise = fit.rmse * math.sqrt(fit.n_samples / max(1, fit.n_samples - 1 - 2 * len(fit.relax)))
        horizon = max(self.planned, elapsed)
        forecast = {name: k * v for name, v in
                    forecast_relative(fit, noise, horizon, self.rate).items()}
        grid = np.linspace(0.0, elapsed, DRAW_POINTS)
        return LiveFitState(elapsed, self.planned, shown.g_e, shown.relax, stderr,
                            max(fit.terms_resolved, 0), fit.not_resolved, fit.n_samples,
                            relative, forecast, fit.relax,
                            {name: k * v for name, v in fit.stderr.items()}, fit.g_e,
                            bin_means(tb, gb, DRAW_POINTS),
                            (grid, model(shown.g_e, shown.relax, grid),
                             k * band(shown, tb, n, noise, grid)), noise)


def correlated_inflation(white: float, correlated: float, tau: float, rate: float,
                         span: float) -> float:
    """How much wider the standard error of a mean over ``span`` s of samples at ``rate`` Hz
    is than a white-noise fit takes it: noise of a white part ``white`` and an
    Ornstein-Uhlenbeck part ``correlated`` with correlation time ``tau`` (s), both rms (any
    one unit), as bring-up measures them (issue 30). The fit sees the two parts' total
    variance per sample and divides it by the samples; the OU part's mean over the span has
    the variance ``c^2 (2/m) (1/(1-phi) - phi (1 - phi^m) / (m (1-phi)^2))`` instead,
    ``phi = exp(-1/(rate tau))``, ``m`` the samples: a parameter the fit takes from the
    whole hold is that much less certain. 1 without a correlated part."""
    m = max(1.0, rate * span)
    if not (correlated > 0 and tau > 0 and math.isfinite(m)):
        return 1.0
    phi = math.exp(-1.0 / (rate * tau))
    ou = correlated ** 2 * (2 / m) * (1 / (1 - phi) - phi * (1 - phi ** m) / (m * (1 - phi) ** 2))
    ou -= correlated ** 2 / m  # the sum counts each sample's own variance twice
    true = white ** 2 / m + ou
    assumed = (white ** 2 + correlated ** 2) / m
    return math.sqrt(max(true / assumed, 1.0))


#: Residual noise over the rig's measured white noise above which the white-noise assumption
#: (and the errors and forecasts that rest on it) is reported as not holding.
WHITE_NOISE_RATIO = 1.5


def white_noise_check(residual: float, white: float) -> str | None:
    """Why the fit's white-noise assumption fails (one line), or None: the residuals' rms
    ``residual`` against the instrument's white noise ``white`` measured at bring-up (both in
    the fit's units). Larger residuals mean noise the fit does not model (drift, 1/f, a
    sample that moves) or a model that misses the data: its intervals are then too narrow."""
    if not (math.isfinite(residual) and math.isfinite(white) and white > 0):
        return None
    ratio = residual / white
    if ratio <= WHITE_NOISE_RATIO:
        return None
    return (f"live fit: residuals {ratio:.2g}x the rig's white noise measured at bring-up: "
            "the fit's white-noise assumption does not hold here (drift, 1/f noise or a model "
            "that misses the data); its intervals and forecast are too narrow")


def _fit_exact(tb: FloatArray, gb: FloatArray, n: FloatArray, within: float, terms: int,
               start: FloatArray) -> tuple[RelaxationFit, float]:
    w = np.sqrt(n)

    def residual(p: FloatArray) -> FloatArray:
        return w * (_value(p, tb, terms) - gb)

    def jacobian(p: FloatArray) -> FloatArray:
        return w[:, None] * _jacobian(p, tb, terms)

    lower = [0.0] + [0.0, 1e-12] * terms
    with np.errstate(over="ignore", invalid="ignore"):  # wild trial steps of a 2-term fit
        res = least_squares(residual, np.maximum(start, np.array(lower) + 1e-12),
                            jac=jacobian, bounds=(lower, np.inf), x_scale="jac",
                            max_nfev=MAX_EVALUATIONS)
    p = res.x
    total = float(n.sum())
    rss = within + float(np.sum(res.fun ** 2))
    dof = max(1.0, total - p.size)
    err = standard_errors(res.jac, rss / dof, np.asarray(res.active_mask) != 0)
    order = sorted(range(terms), key=lambda i: -p[2 + 2 * i])
    relax = tuple(RelaxationTerm(float(p[1 + 2 * i]), float(p[2 + 2 * i])) for i in order)
    stderr = {"G_e": float(err[0])}
    for k, i in enumerate(order, 1):
        stderr[f"G_{k}"] = float(err[1 + 2 * i])
        stderr[f"tau_{k}"] = float(err[2 + 2 * i])
    fit = RelaxationFit(float(p[0]), relax, 0.0, math.sqrt(rss / total), stderr, int(total))
    return fit, float(res.cost)


def fit_binned(tb: FloatArray, gb: FloatArray, n: FloatArray, within: float, terms: int,
               warm: dict[int, FloatArray] | None = None, grid: bool = True
               ) -> RelaxationFit:
    """Fit 1..``terms`` terms to bin means ``gb`` at ``tb`` with counts ``n`` (weights) and
    say how many are resolved, by the rules of ``fit_relaxation``.

    Each term count starts from the grid search of ``fit_relaxation`` on at most
    :data:`_GRID_BINS` bins (when ``grid`` or without a warm start) and, when ``warm`` holds
    one, from the previous refit's parameters; the better is kept (``warm`` is updated).
    """
    warm = {} if warm is None else warm
    total = int(n.sum())
    gmean = float(np.sum(n * gb) / total)
    flat_rss = max(within + float(np.sum(n * (gb - gmean) ** 2)), 1e-300)
    simpler_bic = total * math.log(flat_rss / total) + math.log(total)
    tg, gg = bin_means(tb, gb, _GRID_BINS)

    def one(k: int) -> RelaxationFit:
        starts = [warm[k]] if k in warm else []
        if grid or not starts:
            starts.append(np.array(_grid_start(tg, gg, k)))
        best = min((_fit_exact(tb, gb, n, within, k, start) for start in starts),
                   key=lambda candidate: candidate[1])[0]
        warm[k] = _params(best)
        return best

    return resolve_terms((one(k) for k in range(1, terms + 1)), simpler_bic)


def _params(fit: RelaxationFit) -> FloatArray:
    return np.array([fit.g_e, *[x for r in fit.relax for x in (r.g, r.tau)]])


def band(fit: RelaxationFit, tb: FloatArray, n: FloatArray, noise: float, t: FloatArray
         ) -> FloatArray:
    """Standard deviation (Pa) of the fitted curve at ``t``: ``sqrt(diag(J C J^T))`` with the
    fit's covariance ``C`` from bins ``tb`` with counts ``n`` and white noise ``noise`` (Pa);
    NaN when the covariance is singular or ill-conditioned."""
    terms = len(fit.relax)
    p = _params(fit)
    jac = np.sqrt(n)[:, None] * _jacobian(p, tb, terms)
    scale = np.linalg.norm(jac, axis=0)
    if not np.all(np.isfinite(scale) & (scale > 0)):
        return np.full(t.shape, math.nan)
    _, sv, vt = np.linalg.svd(jac / scale, full_matrices=False)
    if sv[-1] <= 0 or sv[0] / sv[-1] > MAX_CONDITION:
        return np.full(t.shape, math.nan)
    at = _jacobian(p, t, terms) / scale @ (vt.T / sv)
    return np.asarray(noise * np.sqrt(np.sum(at * at, axis=1)), dtype=float)


def forecast_relative(fit: RelaxationFit, noise: float, until: float, rate: float
                      ) -> dict[str, float]:
    """Each time constant's relative standard error if the hold ran to ``until`` s at
    ``rate`` Hz with white noise ``noise`` (Pa) and the fitted model were the truth (NaN when
    the covariance would not determine it)."""
    terms = len(fit.relax)
    p = _params(fit)
    edges = np.linspace(0.0, until, _FORECAST_POINTS + 1)
    t = 0.5 * (edges[:-1] + edges[1:])
    count = max(1.0, until * rate / _FORECAST_POINTS)
    jac = math.sqrt(count) * _jacobian(p, t, terms)
    err = standard_errors(jac, noise * noise, np.zeros(p.size, dtype=bool))
    return {f"tau_{k}": float(err[2 + 2 * (k - 1)]) / r.tau
            for k, r in enumerate(fit.relax, 1)}


@dataclass(frozen=True)
class StopRule:
    """When an adaptive hold may end: every time constant of the reported fit has a relative
    standard error at most ``target``, at least ``terms`` terms are resolved, ``min_hold`` s
    have passed, on ``consecutive`` refits in a row."""

    target: float
    terms: int = 1
    min_hold: float = 0.0
    consecutive: int = 2

    def met(self, state: LiveFitState) -> bool:
        """Whether this one refit meets the target."""
        if state.elapsed < self.min_hold or state.terms_resolved < self.terms:
            return False
        rel = [state.relative.get(f"tau_{k}", math.nan) for k in range(1, len(state.relax) + 1)]
        return bool(rel) and all(math.isfinite(r) and r <= self.target for r in rel)

    def done(self, history: list[LiveFitState]) -> bool:
        """Whether the last ``consecutive`` refits all meet the target."""
        last = history[-self.consecutive:]
        return len(last) == self.consecutive and all(self.met(s) for s in last)

    def describe(self) -> str:
        terms = f", {self.terms} terms resolved" if self.terms > 1 else ""
        return (f"every tau to {self.target * 100:g} % (1 s.e.){terms}, on {self.consecutive} "
                f"refits in a row, not before {self.min_hold:g} s")
