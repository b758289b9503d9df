"""The recorded force's quantiser: an ADC's code lattice read off a record, and what Gaussian
noise before it does to the mean and spread of the codes (docs/decisions/0270).

A 14-bit ADC records ``Q(x + n)``: the signal ``x`` plus analogue noise ``n`` (rms ``sigma``),
rounded to a lattice of step ``q``. Averaged over many samples this is not ``x``: its mean is
``x + b(x)`` with ``b`` a periodic function of where ``x`` sits between two codes, of amplitude
up to ``q/2`` when ``sigma << q`` and vanishing as ``exp(-2 pi^2 sigma^2 / q^2)`` once the
noise dithers it. ``b`` follows the signal, not the noise: over a slowly relaxing hold it is a
slow, smooth error that does not average away, so a fit that ignores it reports standard errors
that shrink with the sample count while its error does not. :class:`DitheredQuantiser` gives
``b``, its slope and the codes' second moment exactly (sums over codes), so a fit can model the
codes' mean instead of ``x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq, minimize_scalar
from scipy.special import ndtr

from gelrig.instrument.physics.contact import FloatArray

#: sqrt(2 pi), as scipy.stats computes it for the normal density.
_SQRT_2PI = np.sqrt(2 * np.pi)


def _norm_pdf(z: FloatArray) -> FloatArray:
    """The standard normal density, the same operations as ``scipy.stats.norm.pdf`` (whose
    package import costs a start-up; ``ndtr`` is its cdf)."""
    return np.asarray(np.exp(-z**2 / 2.0) / _SQRT_2PI, dtype=float)


#: Points of the tabulated functions over one code step.
_TABLE = 1024
#: Tolerance (in steps) with which every value of a record must sit on its lattice.
_ON_LATTICE = 1e-4
#: A record is quantised only if it has at most this fraction of distinct values.
_MAX_DISTINCT = 0.25
#: Smallest noise the model resolves, in code steps (below it the table is a staircase).
_MIN_SIGMA = 0.02
#: Largest noise modelled, in code steps: the codes' mean is then the signal to 1e-300.
_MAX_SIGMA = 8.0


@dataclass(frozen=True)
class Lattice:
    """The values a quantised record can take: ``phase + k * step`` (same unit as the record)."""

    step: float
    phase: float


def find_lattice(values: ArrayLike) -> Lattice | None:
    """The code lattice of a record, or None when it is not quantised (too many distinct
    values, or values off any common step)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    u = np.unique(v)
    span = float(u[-1] - u[0])
    # values one rounding error apart (a force rebuilt from G(t)) are one code
    u = u[np.concatenate(([True], np.diff(u) > 1e-9 * span))]
    if u.size < 3 or u.size > _MAX_DISTINCT * v.size:
        return None
    # the codes most samples sit on first: a few samples under another tare (a zero that is
    # a mean of N codes lies on a lattice N times finer) would otherwise make the finest
    # common lattice of both, with one code in N used, and a quantiser of the wrong step
    mostly = _mostly_on_lattice(v, u)
    if mostly is not None:
        return mostly
    step = float(np.min(np.diff(u)))
    k = (u - u[0]) / step
    codes = np.round(k)
    if float(np.max(np.abs(k - codes))) > _ON_LATTICE:
        return None
    if u.size < _MIN_OCCUPIED * (codes[-1] + 1):  # interleaved lattices, not one
        return None
    if codes[-1] > 0:  # the step from all codes, not the one smallest difference
        step = float(np.dot(codes, u - u[0]) / np.dot(codes, codes))
    return Lattice(step, float(u[0] % step))


#: Fewest of a record's samples on one lattice for it to count as quantised when a few are
#: not: a sample recorded under the previous tare at a record's edge (one in 32,000 on the
#: compression ramp) put the whole ramp off the quantised fit (first touch 0.66 um early at
#: 0.05 mN).
_MOSTLY = 0.99

#: Fewest of the codes between a record's lowest and highest value that its samples use for
#: the record to count as on one lattice (a quantised signal with noise uses nearly all).
_MIN_OCCUPIED = 0.2


def _mostly_on_lattice(v: FloatArray, u: FloatArray) -> Lattice | None:
    """The lattice that at least :data:`_MOSTLY` of the samples ``v`` (distinct values
    ``u``) sit on: its step the typical spacing of the distinct values, its phase the most
    common value's; None when no lattice holds that many."""
    step = float(np.median(np.diff(u)))
    if not step > 0:
        return None
    values, counts = np.unique(v, return_counts=True)
    anchor = float(values[int(np.argmax(counts))])
    k = (v - anchor) / step
    if float(np.mean(np.abs(k - np.round(k)) <= _ON_LATTICE)) < _MOSTLY:
        return None
    ku = (u - anchor) / step
    on = np.abs(ku - np.round(ku)) <= _ON_LATTICE
    codes = np.round(ku[on])
    if np.any(codes != 0):
        step = float(np.dot(codes, u[on] - anchor) / np.dot(codes, codes))
    return Lattice(step, float(anchor % step))


class DitheredQuantiser:
    """Mean error ``b(x)``, its slope and the second moment ``E[(Q(x+n) - x)^2]`` of a lattice
    with Gaussian noise of rms ``sigma`` before it; tabulated over one step, exact sums over
    the codes within 8 sigma."""

    def __init__(self, lattice: Lattice, sigma: float):
        q = lattice.step
        self.lattice = lattice
        self.sigma = min(max(float(sigma), _MIN_SIGMA * q), _MAX_SIGMA * q)
        s = self.sigma / q  # in steps
        u = np.linspace(0.0, 1.0, _TABLE + 1)  # where x sits above a code, in steps
        reach = math.ceil(8.0 * s) + 1
        j = np.arange(-reach, reach + 2)[:, None]  # codes relative to the one below x
        p = ndtr((j + 0.5 - u) / s) - ndtr((j - 0.5 - u) / s)
        self._u = u
        self._bias = q * (np.sum(j * p, axis=0) - u)
        self._moment = q * q * np.sum((j - u) ** 2 * p, axis=0)
        # d E[Q]/dx: the density of code edges under the noise
        self._slope = np.sum(_norm_pdf((j - 0.5 - u) / s), axis=0) / s - 1.0

    def _where(self, x: ArrayLike) -> FloatArray:
        return np.mod((np.asarray(x, dtype=float) - self.lattice.phase) / self.lattice.step, 1.0)

    def bias(self, x: ArrayLike) -> FloatArray:
        """``E[Q(x + n)] - x``."""
        return np.interp(self._where(x), self._u, self._bias)

    def slope(self, x: ArrayLike) -> FloatArray:
        """``d b / d x`` (so the codes' mean moves by ``1 + slope`` per unit of ``x``)."""
        return np.interp(self._where(x), self._u, self._slope)

    def moment(self, x: ArrayLike) -> FloatArray:
        """``E[(Q(x + n) - x)^2]``."""
        return np.interp(self._where(x), self._u, self._moment)


def fit_sigma(lattice: Lattice, x: ArrayLike, recorded: ArrayLike) -> float:
    """The analogue noise (rms) that makes the codes' mean square deviation from the signal
    ``x`` what it is in the ``recorded`` codes (``E[(Q - x)^2]`` grows with sigma).

    Below the smallest resolvable noise, that one; the noise of a record is read off the
    record itself, so no instrument setting has to be known.
    """
    xs = np.asarray(x, dtype=float)
    target = float(np.mean((np.asarray(recorded, dtype=float) - xs) ** 2))
    q = lattice.step
    # a subsample of the signal is enough for the mean over where it sits between codes
    sample = xs[:: max(1, xs.size // 20_000)]

    def gap(sigma: float) -> float:
        return float(np.mean(DitheredQuantiser(lattice, sigma).moment(sample))) - target

    lo, hi = _MIN_SIGMA * q, min(math.sqrt(target) + q, _MAX_SIGMA * q)
    if gap(lo) >= 0:
        return lo
    if gap(hi) <= 0:
        return hi
    return float(brentq(gap, lo, hi, xtol=1e-4 * q))


def baseline_level(values: ArrayLike, lattice: Lattice, sigma: float) -> tuple[float, float]:
    """The true level of a constant signal recorded as ``values`` on ``lattice`` with
    Gaussian noise ``sigma`` before it, and its standard error: the maximum-likelihood level
    of the codes' counts (each code's probability is the noise's mass between its edges).

    The mean of such codes is off by ``b(level)`` (up to half a code when the noise is small);
    this is not. When the codes do not pin the level down (all on one code, little noise), the
    standard error is at least a uniform spread over the width the likelihood leaves open.
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    q, phase = lattice.step, lattice.phase
    s = min(max(float(sigma), _MIN_SIGMA * q), _MAX_SIGMA * q)
    codes, counts = np.unique(np.round((v - phase) / q), return_counts=True)
    upper, lower = (codes + 0.5) * q + phase, (codes - 0.5) * q + phase

    def nll(level: float) -> float:
        p = ndtr((upper - level) / s) - ndtr((lower - level) / s)
        return -float(np.dot(counts, np.log(np.maximum(p, 1e-300))))

    centre = float(np.mean(v))
    res = minimize_scalar(nll, bounds=(centre - q - 3 * s, centre + q + 3 * s),
                          method="bounded", options={"xatol": 1e-6 * q})
    level = float(res.x)
    h = 1e-3 * s
    curvature = (nll(level + h) - 2 * nll(level) + nll(level - h)) / (h * h)
    fisher = 1.0 / math.sqrt(curvature) if curvature > 0 else math.inf
    # the level's spread where the log likelihood is within 1/2 of its best (a flat top)
    grid = np.linspace(level - q, level + q, 201)
    flat = grid[np.array([nll(x) for x in grid]) <= nll(level) + 0.5]
    width = float(flat[-1] - flat[0]) if flat.size > 1 else 0.0
    return level, max(fisher if math.isfinite(fisher) else 0.0, width / math.sqrt(12.0))
