"""The plate-sphere contact's unloading model: cutoff (the paper's) or MDR, the same while the
contact grows, apart on the way out."""

import numpy as np
import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.plate_contact import PlateSphereContact

MAT = Material.of(5e3, [(5e3, 20.0)])  # half the modulus relaxes: the models part clearly
R, TOUCH, DEPTH, T = 9.3e-3, 1e-3, 0.5e-3, 20.0


def triangle(t):
    """In to DEPTH over T seconds and back out over the next T."""
    return TOUCH + DEPTH * (1 - np.abs(np.asarray(t) / T - 1))


def forces(unloading):
    t = np.linspace(0.0, 2 * T, 4001)
    contact = PlateSphereContact(MAT, R, TOUCH, triangle, vectorized=True, unloading=unloading)
    return t, contact.force_on_grid(0.0, float(t[1] - t[0]), t.size)


def test_loading_agrees_and_unloading_differs():
    t, cutoff = forces("cutoff")
    _, mdr = forces("mdr")
    loading, unloading = t <= T, (t > T) & (t < 2 * T)
    peak = cutoff.max()
    # the same up to the models' discretisations while the contact grows
    assert np.abs(cutoff[loading] - mdr[loading]).max() < 0.002 * peak
    gap = np.abs(cutoff[unloading] - mdr[unloading]).max()
    assert gap > 0.02 * peak, (gap, peak)


def test_default_is_the_cutoff():
    t = np.linspace(0.0, 2 * T, 4001)
    plain = PlateSphereContact(MAT, R, TOUCH, triangle, vectorized=True)
    assert plain.force_on_grid(0.0, float(t[1] - t[0]), t.size) == pytest.approx(
        forces("cutoff")[1])


def test_unknown_model_is_refused():
    with pytest.raises(ConfigError, match="unloading"):
        PlateSphereContact(MAT, R, TOUCH, triangle, unloading="ting")
