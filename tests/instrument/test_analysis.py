"""Relaxation fits recover known parameters from noisy simulated holds."""

import numpy as np
import pytest

from instrument import paper
from instrument.analysis import (
    contact_length,
    estimate_first_touch,
    fit_hold,
    fit_relaxation,
    modulus_history,
)
from instrument.compression import ramp_hold
from instrument.contact import Material
from instrument.errors import ConfigError

R, D, V = paper.R_COMPRESSION, paper.DEPTH_HOLD, paper.RAMP_SPEED


def noisy_hold(material, seed, noise=2e-4, dt=0.01):
    rec = ramp_hold(R, D, V, 3000.0, material, dt=dt)
    rng = np.random.default_rng(seed)
    return rec, rec.force + rng.normal(0, noise, rec.force.size)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_term_fit_recovers_parameters(seed):
    rec, force = noisy_hold(paper.PLATES, seed)
    fit = fit_hold(rec.t, force, R, D, terms=1, delta=rec.delta)
    assert fit.g_e == pytest.approx(7146.0, rel=0.005)
    assert fit.relax[0].tau == pytest.approx(1413.0, rel=0.02)
    corrected = fit.extra["relax_ramp_corrected"][0]
    assert corrected["G"] == pytest.approx(630.0, rel=0.03)
    # The stated uncertainties are honest: the truth lies within a few standard errors.
    assert abs(fit.g_e - 7146.0) < 5 * fit.stderr["G_e"]
    assert abs(fit.relax[0].tau - 1413.0) < 5 * fit.stderr["tau_1"]
    assert fit.rmse == pytest.approx(modulus_history(2e-4, D, R), rel=0.1)


@pytest.mark.parametrize("seed", [3, 4])
def test_two_term_fit_recovers_parameters(seed):
    rec, force = noisy_hold(paper.SHELL, seed)
    fit = fit_hold(rec.t, force, R, D, terms=2, delta=rec.delta)
    assert fit.g_e == pytest.approx(13915.0, rel=0.005)
    assert [r.tau for r in fit.relax] == pytest.approx([1898.0, 172.0], rel=0.03)
    corrected = [r["G"] for r in fit.extra["relax_ramp_corrected"]]
    assert corrected == pytest.approx([2540.0, 504.0], rel=0.05)
    one = fit_hold(rec.t, force, R, D, terms=1, delta=rec.delta)
    assert one.rmse > 1.5 * fit.rmse  # one exponential is not enough in the shell


def test_fit_without_overlap_finds_the_hold_from_the_force():
    rec, force = noisy_hold(paper.PLATES, 7)
    fit = fit_hold(rec.t, force, R, D, terms=1)
    assert fit.t0 == pytest.approx(rec.t_hold, abs=1.0)
    assert fit.g_e == pytest.approx(7146.0, rel=0.005)
    assert fit.relax[0].tau == pytest.approx(1413.0, rel=0.03)


def test_fit_leaves_out_the_retract_after_the_hold():
    rec, force = noisy_hold(paper.PLATES, 8)
    back = np.linspace(1.0, 0.0, 2001)[1:]  # a 20 s retract: overlap and force fall back
    t = np.concatenate((rec.t, rec.t[-1] + 0.01 * np.arange(1, 2001)))
    delta = np.concatenate((rec.delta, rec.delta[-1] * back))
    with_retract = np.concatenate((force, force[-1] * back**1.5))
    fit = fit_hold(t, with_retract, R, D, terms=1, delta=delta)
    held = fit_hold(rec.t, force, R, D, terms=1, delta=rec.delta)
    assert fit.n_samples == held.n_samples
    assert fit.g_e == pytest.approx(held.g_e, rel=1e-9)


def test_fit_needs_a_hold():
    t = np.linspace(0, 10, 100)
    with pytest.raises(ConfigError, match="samples"):
        fit_hold(t, np.ones(100), R, D, delta=np.full(100, np.nan))


def test_fit_needs_enough_samples_and_valid_terms():
    with pytest.raises(ConfigError, match="samples"):
        fit_relaxation(np.arange(5.0), np.ones(5))
    with pytest.raises(ConfigError, match="terms"):
        fit_relaxation(np.arange(50.0), np.ones(50), terms=3)


def test_flat_data_fits_without_crashing():
    t = np.linspace(0, 100, 500)
    fit = fit_relaxation(t, np.full_like(t, 5000.0), terms=1)
    assert fit.g_e + fit.relax[0].g == pytest.approx(5000.0, rel=1e-3)


def test_fit_json_shape():
    t = np.linspace(0, 3000, 3001)
    g = Material.of(7000, [(600, 1400)]).modulus(t)
    d = fit_relaxation(t, g).as_dict()
    assert set(d) == {"G_e", "relax", "t0_s", "rmse", "stderr"}
    assert set(d["relax"][0]) == {"G", "tau"}
    assert set(d["stderr"]) == {"G_e", "G_1", "tau_1"}


def test_contact_length():
    x = np.linspace(0, 10, 101)
    f = np.where((x > 2) & (x < 7), 1.0, 0.0)
    assert contact_length(x, f) == pytest.approx(4.8)
    assert contact_length(x, np.zeros_like(x)) == 0.0


def test_first_touch_needs_the_force_to_rise_over_several_positions() -> None:
    z = np.r_[np.linspace(5e-3, 6e-3, 20), np.full(10, 6.3e-3)]  # the stage stood still
    f = np.r_[np.zeros(20), np.linspace(0.01, 0.05, 10)]
    with pytest.raises(ConfigError, match="fewer than 3 plate positions"):
        estimate_first_touch(z, f)
