"""The noise of a sampled signal: one robust estimate used by acquisition and analysis alike.

Formula (docs/decisions/0051): ``sigma = 1.4826 * MAD(diff(x)) / sqrt(2)``, with ``MAD`` the
median absolute deviation from the median. Why this one:

- first differences drop any offset and slow drift (a baseline, a relaxing hold), so the
  estimate sees the noise, not the signal;
- taking the deviation from the *median* difference also drops a steady slope (a ramp at
  constant speed), which ``median(|diff|)`` would count as noise;
- the median ignores spikes and the few large steps of a contact edge or a hold start;
- ``1.4826`` makes the MAD a consistent estimate of a Gaussian standard deviation, and the
  difference of two independent samples has ``sqrt(2)`` times the noise of one.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

#: MAD of a normal distribution in units of its standard deviation, inverted.
MAD_TO_SIGMA = 1.4826
#: Samples the estimate needs (two differences, so that a deviation from their median exists).
MIN_SAMPLES = 3


def robust_sigma(x: ArrayLike) -> float:
    """Standard deviation of the white noise on ``x`` (NaN for fewer than 3 samples)."""
    d = np.diff(np.asarray(x, dtype=float))
    if d.size < MIN_SAMPLES - 1:
        return math.nan
    return MAD_TO_SIGMA * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0)


def resolution_step(x: ArrayLike) -> float:
    """Smallest difference between two distinct values of ``x`` (0 if it is constant).

    A quantised, nearly noise-free record has a robust sigma of 0; one resolution step is
    then the honest floor of its noise.
    """
    values = np.unique(np.asarray(x, dtype=float))
    return float(np.min(np.diff(values), initial=math.inf)) if values.size > 1 else 0.0
