"""Relaxation fits recover known parameters from noisy simulated holds."""

import numpy as np
import pytest

from gelrig.instrument.analysis.relaxation import (
    _grid_batched,
    _grid_each,
    contact_length,
    estimate_first_touch,
    fit_hold,
    fit_relaxation,
    format_stderr,
    loading_law,
    modulus_history,
    standard_errors,
)
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold
from gelrig.instrument.physics.contact import Material, RelaxationTerm, normal_force

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
    assert set(d) == {"G_e", "relax", "t0_s", "rmse", "stderr", "terms_resolved"}
    assert d["terms_resolved"] == 1
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


# -- which terms the data resolve (docs/decisions/0160) ---------------------------------------

@pytest.mark.parametrize("seed", [11, 12])
def test_a_second_term_the_data_do_not_hold_is_not_reported(seed):
    rec, force = noisy_hold(paper.PLATES, seed)  # one term in the truth
    fit = fit_hold(rec.t, force, R, D, terms=2, delta=rec.delta)
    assert fit.terms_resolved == 1
    assert fit.not_resolved.startswith("second term not resolved: ")
    d = fit.as_dict()
    assert d["terms_resolved"] == 1 and d["terms_requested"] == 2
    assert len(d["relax"]) == 1 and len(d["unresolved_fit"]["relax"]) == 2
    assert d["relax"][0]["tau"] == pytest.approx(1413.0, rel=0.02)
    assert {"G_e", "relax", "t0_s", "rmse", "stderr", "relax_ramp_corrected"} <= set(d)


@pytest.mark.parametrize("seed", [13, 14])
def test_the_shells_two_terms_are_resolved_longest_first(seed):
    rec, force = noisy_hold(paper.SHELL, seed)
    fit = fit_hold(rec.t, force, R, D, terms=2, delta=rec.delta)
    assert fit.terms_resolved == 2 and fit.not_resolved == ""
    taus = [term["tau"] for term in fit.as_dict()["relax"]]
    assert taus == pytest.approx([1898.0, 172.0], rel=0.05)  # longest first


def test_a_singular_covariance_gives_undetermined_errors():
    """The issue's decimated copy: 31 samples of a one-term hold asked for two terms."""
    rec, force = noisy_hold(paper.PLATES, 0)
    fit = fit_hold(rec.t[::1000], force[::1000], R, D, terms=2, delta=rec.delta[::1000])
    assert fit.terms_resolved == 1 and "undetermined" in fit.not_resolved
    assert all(np.isnan(v) for v in fit.stderr.values())
    assert [format_stderr(v) for v in fit.stderr.values()] == ["undetermined"] * 5
    assert all(v is None for v in fit.as_dict()["unresolved_fit"]["stderr"].values())


def test_standard_errors_of_a_parameter_the_model_ignores_are_undetermined():
    t = np.linspace(0.0, 1.0, 50)
    jac = np.column_stack([np.ones_like(t), t, np.zeros_like(t)])  # the last does nothing
    err = standard_errors(jac, 1.0, np.zeros(3, bool))
    assert np.all(np.isfinite(err[:2]) & (err[:2] > 0)) and np.isnan(err[2])
    err = standard_errors(jac, 1.0, np.array([False, True, False]))  # one at its bound
    assert np.isfinite(err[0]) and np.isnan(err[1:]).all()
    twin = np.column_stack([np.ones_like(t), t, t * (1 + 1e-12)])  # two do the same
    assert np.isnan(standard_errors(twin, 1.0, np.zeros(3, bool))).all()


def test_flat_data_resolve_no_term():
    t = np.linspace(0, 100, 500)
    g = 5000.0 + np.random.default_rng(3).normal(0.0, 1.0, t.size)
    fit = fit_relaxation(t, g, terms=1)
    assert fit.terms_resolved == 0 and fit.not_resolved.startswith("first term not resolved")


def test_first_touch_on_a_slow_ramp_allows_for_relaxation():
    """The paper's ramp (37 um/s, 30 s) into the shell material: it relaxes while loading,
    which a pure d^1.5 fit takes for a touch about a micrometre early."""
    touch = 6.2e-3
    t = np.arange(0.0, (D + 1e-4) / V, 0.01)
    z = touch - 1e-4 + V * t
    force = normal_force(t, np.maximum(z - touch, 0.0), paper.SHELL, R)
    plain = estimate_first_touch(z, force)
    relaxing = estimate_first_touch(z, force, relaxing=True)
    assert abs(plain.position - touch) > 0.5e-6
    assert relaxing.position == pytest.approx(touch, abs=0.05e-6)
    assert relaxing.softening < 0  # the modulus falls as the ramp goes on
    rng = np.random.default_rng(4)
    noisy = [estimate_first_touch(z, force + rng.normal(0.0, 2e-4, z.size), relaxing=True)
             .position - touch for _ in range(8)]
    assert abs(float(np.mean(noisy))) < 0.3e-6 and max(map(abs, noisy)) < 1e-6


def test_first_touch_on_a_ramp_as_long_as_tau_takes_the_materials_own_loading_law():
    """A material relaxing within the ramp (tau 40 s, the paper's 30 s ramp): the first-order
    softening leaves the touch early by several times its standard error; the fitted
    material's loading law (ADR 0375) puts it where it is."""
    touch, fast = 6.2e-3, Material.of(7000.0, [(2500.0, 40.0)])
    t = np.arange(0.0, (D + 1e-4) / V, 0.01)
    z = touch - 1e-4 + V * t
    force = normal_force(t, np.maximum(z - touch, 0.0), fast, R)
    law = loading_law(t, fast)
    assert estimate_first_touch(z, force, relaxing=True).position - touch < -1e-6
    assert estimate_first_touch(z, force, law=law).position == pytest.approx(touch, abs=1e-9)
    rng = np.random.default_rng(5)
    found = [estimate_first_touch(z, force + rng.normal(0.0, 2e-4, z.size), law=law)
             for _ in range(20)]
    errors = np.array([f.position - touch for f in found])
    stderr = float(np.median([f.stderr for f in found]))
    assert abs(float(errors.mean())) < 3 * stderr / np.sqrt(errors.size)  # no bias
    assert 0.7 < float(errors.std(ddof=1)) / stderr < 1.3  # and an honest standard error


@pytest.mark.parametrize("seed", range(12))
def test_first_touch_after_millimetres_of_noisy_probing(seed):
    """A contact search probing 6.2 mm at 0.3 mm/s and 100 Hz with a 0.5 mN load cell stops
    at 5 mN: a few noise samples far before contact rise above 0.3 of the peak, which tilted
    the fit's start line so that it found no touch (gelrig's rig at 0.5 mN, 2026-11-28)."""
    touch = 6.2e-3
    z = np.arange(0.0, 6.45e-3, 3e-6)
    force = normal_force(z / 0.3e-3, np.maximum(z - touch, 0.0),
                         Material.of(paper.PLATES.g_instant), R)
    noisy = force + np.random.default_rng(seed).normal(0.0, 5e-4, z.size)
    end = int(np.argmax(noisy > 5e-3))
    found = estimate_first_touch(z[:end + 1], noisy[:end + 1])
    assert abs(found.position - touch) < 4 * found.stderr + 1e-6, (found.position, found.stderr)


@pytest.mark.parametrize("seed", range(24))
def test_the_batched_grid_search_starts_where_the_one_at_a_time_search_does(seed):
    """The grid of time constants solved at once (normal equations, then a shortlist solved
    one at a time) picks the same combination and amplitudes as solving each combination by
    itself (issue 31): over materials, spans, bin counts and noise from 0.3x to 1000x the
    paper's."""
    rng = np.random.default_rng(seed)
    material = (paper.PLATES, paper.SHELL, Material(5000.0, (RelaxationTerm(800.0, 30.0),)),
                Material(5000.0))[seed % 4]
    span, bins = float(rng.choice([20.0, 300.0, 3000.0])), int(rng.choice([50, 200, 600]))
    t = np.linspace(0.0, span, bins) + rng.uniform(0.0, 1.0)
    g = material.modulus(t) + rng.normal(0.0, 5.0 * float(rng.choice([0.3, 10, 1000])), bins)
    for terms in (1, 2):
        dt = float(np.median(np.diff(t)))
        taus = np.geomspace(max(3 * dt, span * 1e-4), 20 * span, 60 if terms == 1 else 32)
        batched, each = _grid_batched(t, g, taus, terms), _grid_each(t, g, taus, terms)
        assert (batched is None) == (each is None)
        if each is not None:
            assert batched[0] == each[0]
            assert np.array_equal(batched[1], each[1])
