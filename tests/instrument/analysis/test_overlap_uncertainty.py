"""The measured overlap's uncertainty in the hold fit's intervals (ADR 0160): the
first-touch refit reports an honest standard error, and it widens every modulus alike."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from gelrig.instrument.analysis.relaxation import estimate_first_touch, fit_hold, with_scale_stderr
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.plate_contact import PlateSphereContact

TOUCH = 6.2e-3


def approach(seed: int, noise: float = 2e-4) -> tuple[np.ndarray, np.ndarray]:
    """A 37 um/s ramp 0.1 mm before to 1.1 mm past first touch at 100 Hz, with white noise."""
    rng = np.random.default_rng(seed)
    speed = 37.26e-6
    t = np.arange(0.0, 1.2e-3 / speed, 0.01)
    z = TOUCH - 0.1e-3 + speed * t
    contact = PlateSphereContact(Material.of(7146.0, [(630.0, 1413.0)]), 18.63e-3 / 2, TOUCH,
                                 lambda ts: TOUCH - 0.1e-3 + speed * ts, vectorized=True)
    return z, contact.force(t) + rng.normal(0.0, noise, t.size)


def test_the_first_touch_standard_error_matches_its_spread() -> None:
    fits = [estimate_first_touch(*approach(seed), relaxing=True) for seed in range(40)]
    errors = [f.position - TOUCH for f in fits]
    reported = statistics.median(f.stderr for f in fits)
    assert 0 < reported < 5e-6
    assert statistics.stdev(errors) / reported == pytest.approx(1.0, abs=0.35)


def test_a_scale_uncertainty_widens_every_modulus_and_leaves_tau() -> None:
    t = np.linspace(0.0, 600.0, 6001)
    delta = np.full(t.size, 1.1178e-3)
    g = Material.of(7146.0, [(630.0, 1413.0)]).modulus(t)
    force = g * 16 / 3 * math.sqrt(18.63e-3 / 2) * delta**1.5 * 0.75  # Hertz with nu = 0.5
    force += np.random.default_rng(1).normal(0.0, 2e-4, t.size)
    plain = fit_hold(t, force, 18.63e-3 / 2, delta, terms=2)
    wide = fit_hold(t, force, 18.63e-3 / 2, delta, terms=2, overlap_stderr=0.5e-6)
    rel = 1.5 * 0.5e-6 / 1.1178e-3
    assert wide.extra["scale_rel_stderr"] == pytest.approx(rel)
    one_a, one_b = plain.fewer, wide.fewer  # the one-term fits, carried by the two-term ones
    assert one_a is not None and one_b is not None
    assert one_b.stderr["G_e"] == pytest.approx(math.hypot(one_a.stderr["G_e"], rel * one_a.g_e))
    assert one_b.stderr["G_1"] == pytest.approx(math.hypot(one_a.stderr["G_1"],
                                                           rel * one_a.relax[0].g))
    assert one_b.stderr["tau_1"] == one_a.stderr["tau_1"]
    assert (one_b.g_e, one_b.relax) == (one_a.g_e, one_a.relax)
    for name, value in plain.stderr.items():  # undetermined stays undetermined
        assert math.isnan(wide.stderr[name]) == math.isnan(value)
    assert (wide.terms_resolved, wide.not_resolved) == (plain.terms_resolved,
                                                       plain.not_resolved)
    assert with_scale_stderr(plain, math.nan) is plain
