"""The contact search's first touch on one approach (``compression_search._touch_of``): fitted
on the stretch before the crossing, and never a touch off the approach (issue 26: a 0.5 mN
load cell with a slow part made a search complete with a touch 77 mm early)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from gelrig.instrument.analysis.relaxation import estimate_first_touch
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import Material, normal_force
from gelrig.protocols.steps.compression_search import _touch_of

TOUCH, SPEED, RATE = 6.2e-3, 0.3e-3, 100.0


def approach(seed: int, white: float, slow: float = 0.0, tau: float = 0.5
             ) -> tuple[np.ndarray, np.ndarray, float]:
    """6.2 mm of probing at 0.3 mm/s and 100 Hz into the paper's plate sphere, stopped at
    5 mN, with white noise and an Ornstein-Uhlenbeck part of rms ``slow``."""
    z = np.arange(0.0, 6.45e-3, SPEED / RATE)
    force = normal_force(z / SPEED, np.maximum(z - TOUCH, 0.0),
                         Material.of(paper.PLATES.g_instant), paper.R_COMPRESSION)
    rng = np.random.default_rng(seed)
    phi = math.exp(-1.0 / (RATE * tau))
    drive = rng.standard_normal(z.size) * slow * math.sqrt(1 - phi * phi)
    wander = lfilter([1.0], [1.0, -phi], drive, zi=[phi * slow * rng.standard_normal()])[0]
    noisy = force + wander + rng.normal(0.0, white, z.size)
    end = int(np.argmax(noisy > 5e-3))
    return z[:end + 1], noisy[:end + 1], float(z[end])


@pytest.mark.parametrize("seed", range(6))
def test_on_white_noise_the_window_keeps_the_whole_approachs_touch(seed):
    z, f, cross = approach(seed, 0.2e-3)
    found = _touch_of(z, f, cross)
    assert found is not None
    assert found == pytest.approx(estimate_first_touch(z, f).position, abs=1.5e-6)
    assert abs(found - TOUCH) < 5e-6


@pytest.mark.parametrize("seed", range(12))
def test_a_wandering_baseline_gives_a_touch_on_the_approach_or_none(seed):
    z, f, cross = approach(seed, 0.2e-3, slow=0.5e-3)
    found = _touch_of(z, f, cross)
    assert found is None or float(z.min()) <= found <= cross


@pytest.mark.parametrize("seed", range(3))
def test_a_drifting_baseline_pulls_the_windowed_touch_far_less(seed):
    """A baseline drifting by 1 mN over the 6 mm of probing: the whole approach's fit puts
    the touch 20-45 um off, the window before the crossing within a few um."""
    z, f, cross = approach(seed, 0.2e-3)
    f = f + 1e-3 * (z / z.max() - 1.0)
    whole = estimate_first_touch(z, f).position
    found = _touch_of(z, f, cross)
    assert found is not None
    assert abs(whole - TOUCH) > 20e-6
    assert abs(found - TOUCH) < 8e-6
