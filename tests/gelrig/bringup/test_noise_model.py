"""The unloaded record's correlated part (issue 30): resolved when there, absent when not."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from gelrig.bringup.loadcell import analyse_noise
from gelrig.bringup.noise_model import correlated_part, drift_uncertainty

RATE, N = 1000.0, 20_000


def _ou(rms: float, tau: float, seed: int) -> np.ndarray:
    a = np.exp(-1 / (RATE * tau))
    z = rms * np.random.default_rng(seed).standard_normal(N)
    return np.asarray(lfilter([np.sqrt(1 - a * a)], [1, -a], z, zi=[a * z[0]])[0])


@pytest.mark.parametrize("seed", range(5))
def test_white_noise_has_no_correlated_part(seed):
    white = 1.4e-3 * np.random.default_rng(seed).standard_normal(N)
    assert correlated_part(white, RATE) is None


@pytest.mark.parametrize("seed", range(5))
def test_a_correlated_part_is_resolved_apart_from_the_white(seed):
    white = 1.4e-3 * np.random.default_rng(100 + seed).standard_normal(N)
    noise = analyse_noise(white + _ou(1.2e-3, 0.05, seed), RATE)
    part = noise.correlated
    assert part is not None
    assert part.rms == pytest.approx(1.2e-3, rel=0.2)
    assert part.tau == pytest.approx(0.05, rel=0.35)
    assert noise.rms == pytest.approx(1.4e-3, rel=0.1)  # the white part only


def test_the_drift_uncertainty_grows_with_the_correlated_part():
    white = drift_uncertainty(1e-3, None, RATE, 20.0)
    assert white == pytest.approx(np.sqrt(12 * 1e-6 / RATE / 20.0 ** 3))
    noise = analyse_noise(1e-3 * np.random.default_rng(0).standard_normal(N) +
                          _ou(1e-3, 0.1, 0), RATE)
    assert noise.correlated is not None
    assert drift_uncertainty(1e-3, noise.correlated, RATE, 20.0) > 5 * white
