"""The unloaded record's correlated part: what white noise and a straight drift leave out.

The twin's force noise (issue 30) is white, plus a drift, plus an Ornstein-Uhlenbeck part of
rms ``sigma`` and correlation time ``tau`` (autocovariance ``sigma^2 exp(-lag / tau)``).
Bring-up resolves that part on block means of :data:`BLOCK` seconds, where the white noise
averages down and a correlation time much longer than the block stays: the autocovariance
of the means at lags 1.. (lag 0 carries the white noise) is fitted with the exponential.
Uncertainties are the record's statistics (a variance estimated over ``T / tau`` correlation
times), approximate and k=1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Block over which the record is averaged before the autocovariance (s), and the longest lag
#: fitted (s): correlation times from about 2 blocks to about a third of it are resolved.
BLOCK, LONGEST_LAG = 0.01, 2.0
#: The fitted variance must exceed this many standard errors of an autocovariance point.
RESOLVED = 5.0


@dataclass(frozen=True)
class Correlated:
    """The correlated part: rms (the record's units), correlation time (s), and their
    relative uncertainties."""

    rms: float
    tau: float
    u_rms: float
    u_tau: float


def correlated_part(rest: np.ndarray, rate: float) -> Correlated | None:
    """The Ornstein-Uhlenbeck part of a detrended record ``rest`` sampled at ``rate``, or None
    when it is not resolved (white noise)."""
    from scipy.optimize import curve_fit

    m = max(1, round(BLOCK * rate))
    k = rest.size // m
    if k < 50:
        return None
    y = rest[: k * m].reshape(k, m).mean(axis=1)
    y = y - y.mean()
    dt = m / rate
    lags = np.arange(1, min(k // 10, round(LONGEST_LAG / dt)) + 1)
    c = np.array([np.mean(y[:-j] * y[j:]) for j in lags])
    c0 = float(np.mean(y * y))
    if c[0] <= RESOLVED * c0 / math.sqrt(k):
        return None

    def model(lag: np.ndarray, var: float, tau: float) -> np.ndarray:
        return np.asarray(var * np.exp(-lag * dt / tau))

    start = (float(c[0]), max(dt, -dt / math.log(min(max(c[1] / c[0], 1e-3), 0.999))))
    try:
        (var, tau), _ = curve_fit(model, lags, c, p0=start,
                                  bounds=([0.0, dt / 2], [np.inf, 10 * lags[-1] * dt]))
    except (RuntimeError, ValueError):
        return None
    if not var > RESOLVED * c0 / math.sqrt(k):
        return None
    record = rest.size / rate
    return Correlated(float(math.sqrt(var)), float(tau), math.sqrt(tau / (2 * record)),
                      math.sqrt(2 * tau / record))


def drift_uncertainty(white: float, part: Correlated | None, rate: float, record: float
                      ) -> float:
    """Standard uncertainty of a straight-line slope over ``record`` seconds of white noise
    ``white`` (rms at ``rate``) plus the correlated ``part`` (its low-frequency density)."""
    density = white ** 2 / rate + (2 * part.rms ** 2 * part.tau if part else 0.0)
    return math.sqrt(12 * density / record ** 3)


__all__ = ["BLOCK", "Correlated", "correlated_part", "drift_uncertainty"]
