"""The load cell's noise analysis on records of known noise, drift and quantisation."""

from __future__ import annotations

import numpy as np
import pytest

from gelrig.bringup.loadcell import analyse_noise, calibration_masses
from gelrig.instrument.contracts.loadcell import LoadCellChain

LSB = 20.0 / 2 ** 14


def _record(rms: float, drift: float = 0.0, n: int = 20000, rate: float = 1000.0,
            seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    v = 0.0123 + drift * t + rms * rng.standard_normal(n)
    return np.round(v / LSB) * LSB


@pytest.mark.parametrize("rms", [0.7e-3, 1.44e-3, 5e-3])
def test_the_white_noise_is_found_through_the_quantiser(rms):
    noise = analyse_noise(_record(rms), 1000.0)
    assert noise.rms == pytest.approx(rms, rel=0.05)
    assert noise.step == pytest.approx(LSB, rel=1e-6)
    assert noise.zero == pytest.approx(0.0123, abs=rms / 50)
    assert 0.5 < noise.low_band < 2.0


def test_a_drift_is_measured_and_kept_out_of_the_rms():
    noise = analyse_noise(_record(1.44e-3, drift=50e-6), 1000.0)
    assert noise.drift == pytest.approx(50e-6, rel=0.05)
    assert noise.rms == pytest.approx(1.44e-3, rel=0.05)


def test_a_random_walk_shows_in_the_spectrum():
    rng = np.random.default_rng(2)
    walk = np.cumsum(rng.standard_normal(20000)) * 1e-4 + rng.standard_normal(20000) * 1e-3
    assert analyse_noise(walk, 1000.0).low_band > 5


def test_the_masses_span_the_cells_range():
    masses = calibration_masses(LoadCellChain(capacity=2.5))
    assert [round(m * 1e3) for m in masses] == [20, 50, 100, 200]
