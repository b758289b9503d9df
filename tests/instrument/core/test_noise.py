"""The one robust noise estimate: white noise through offsets, drifts, ramps and spikes."""

import math

import numpy as np
import pytest

from gelrig.instrument.core.noise import resolution_step, robust_sigma

SIGMA = 0.3


def white(n=20_000, seed=0):
    return np.random.default_rng(seed).normal(0.0, SIGMA, n)


def test_white_noise_gives_its_standard_deviation():
    assert robust_sigma(white()) == pytest.approx(SIGMA, rel=0.03)


def test_offset_drift_and_steady_ramp_are_not_noise():
    n = 20_000
    t = np.arange(n)
    drift = 50.0 + 20.0 * np.sin(2 * math.pi * t / n)  # offset and a slow swing
    ramp = 0.5 * t  # a steady slope larger than the noise on each step
    assert robust_sigma(white(n) + drift) == pytest.approx(SIGMA, rel=0.03)
    assert robust_sigma(white(n) + ramp) == pytest.approx(SIGMA, rel=0.03)


def test_spikes_and_a_step_are_ignored():
    x = white()
    x[::500] += 100.0  # 40 spikes
    x[10_000:] += 1e3  # one step
    assert robust_sigma(x) == pytest.approx(SIGMA, rel=0.05)


def test_too_few_samples_and_constant_records():
    assert math.isnan(robust_sigma([1.0, 2.0]))
    assert robust_sigma(np.full(10, 4.0)) == 0.0
    assert robust_sigma([0.0, 1.0, 2.0]) == 0.0  # a pure ramp has no noise


def test_resolution_step_is_the_smallest_distinct_difference():
    q = 1e-5
    x = q * np.array([3, 5, 4, 4, 7, 3])
    assert resolution_step(x) == pytest.approx(q)
    assert resolution_step(np.full(5, 2.0)) == 0.0
    assert resolution_step([]) == 0.0
