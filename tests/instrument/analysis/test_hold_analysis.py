"""A ramp-and-hold step analysed whole, on modelled records with a known material."""

import math

import numpy as np
import pytest

from gelrig.instrument.analysis.hold_analysis import NoHold, analyse_hold, measured_overlap
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold
from gelrig.instrument.physics.contact import hertz_prefactor, normal_force

R, D, V = paper.R_COMPRESSION, paper.DEPTH_HOLD, paper.RAMP_SPEED
HOLD = 600.0
NOISE = 2e-4  # N
DT = 0.05


@pytest.fixture(scope="module")
def record():
    """Ramp, 600 s hold and a 10 s retract, with noise (the hold step's columns)."""
    rec = ramp_hold(R, D, V, HOLD, paper.PLATES, dt=DT)
    back = np.linspace(1.0, 0.0, 201)[1:]
    t = np.concatenate((rec.t, rec.t[-1] + DT * np.arange(1, back.size + 1)))
    delta = np.concatenate((rec.delta, rec.delta[-1] * back))
    force = np.concatenate((rec.force, rec.force[-1] * back**1.5))
    force = force + np.random.default_rng(5).normal(0.0, NOISE, force.size)
    return rec, t, force, delta


@pytest.fixture(scope="module")
def analysed(record):
    _, t, force, delta = record
    return analyse_hold(t, force, delta, R, D, planned=HOLD)


def test_the_hold_is_found_and_the_retract_left_out(record, analysed):
    rec, t, _, _ = record
    assert t[analysed.span.start] == pytest.approx(rec.t_hold, abs=DT)
    assert analysed.span.end == rec.t.size
    assert analysed.duration == pytest.approx(HOLD, abs=DT)
    assert analysed.samples == analysed.span.samples == analysed.g.size == analysed.t.size
    assert analysed.t[0] == 0.0
    assert not analysed.truncated


def test_modulus_and_fits_recover_the_material(record, analysed):
    rec = record[0]
    g_e, (term,) = paper.PLATES.g_e, paper.PLATES.relax
    one, two = analysed.fits
    assert len(one.relax) == 1 and len(two.relax) == 2
    assert one.g_e == pytest.approx(g_e, rel=0.01)
    assert one.relax[0].tau == pytest.approx(term.tau, rel=0.1)
    # G(t) is the noiseless modelled force over K delta^1.5, to within the noise
    truth = rec.force[-analysed.samples:] / (hertz_prefactor(R) * D**1.5)
    assert float(np.mean(analysed.g - truth)) == pytest.approx(0.0, abs=1.0)
    assert analysed.fit_errors == {}


def test_residuals_are_the_bin_means_less_each_model(analysed):
    res = analysed.residuals(100)
    assert res.t.size == res.g.size == 100 and len(res.residuals) == 2
    one = analysed.fits[0]
    assert res.residuals[0] == pytest.approx(res.g - one.model(res.t))
    # the fitted model leaves only the noise of each bin mean (in Pa)
    noise_g = NOISE / (hertz_prefactor(R) * D**1.5) / math.sqrt(analysed.samples / 100)
    assert float(np.std(res.residuals[0])) == pytest.approx(noise_g, rel=0.3)


def test_a_short_hold_is_flagged_truncated(record):
    _, t, force, delta = record
    assert analyse_hold(t, force, delta, R, D, planned=2 * HOLD).truncated
    assert not analyse_hold(t, force, delta, R, D).truncated  # nothing planned


def test_non_finite_samples_are_left_out(record, analysed):
    _, t, force, delta = record
    force, delta = force.copy(), delta.copy()
    force[1000:1010] = np.nan
    delta[2000] = np.inf
    again = analyse_hold(t, force, delta, R, D, terms=(1,))
    assert again.samples == analysed.samples - 11
    assert again.fits[0].g_e == pytest.approx(analysed.fits[0].g_e, rel=1e-3)


def test_no_hold_when_the_ramp_stops_short_or_there_is_no_data(record):
    _, t, force, delta = record
    with pytest.raises(NoHold, match="never reached the hold depth"):
        analyse_hold(t, force, delta, R, 2 * D)
    with pytest.raises(NoHold, match="no hold data"):
        analyse_hold(t[:10], force[:10], delta[:10], R, D)


def test_failed_fits_are_named_not_raised(record):
    _, t, force, delta = record
    out = analyse_hold(t, force, delta, R, D, terms=(3,))
    assert out.fits == () and set(out.fit_errors) == {3}
    assert "terms" in out.fit_errors[3]
    assert np.all(np.isnan(out.g))


def test_flat_force_fits_a_flat_modulus():
    t = np.arange(0.0, 200.0, 0.1)
    delta = np.minimum(t * 1e-5, 2e-4)
    force = 5000.0 * hertz_prefactor(R) * delta**1.5  # Hertz, no relaxation
    out = analyse_hold(t, force, delta, R, 2e-4, terms=(1,))
    fit = out.fits[0]
    assert fit.g_e + fit.relax[0].g == pytest.approx(5000.0, rel=1e-3)
    assert math.isfinite(fit.rmse)


# -- the measured overlap: first touch refitted on the ramp (docs/decisions/0160) -----------------

TOUCH = 6.2e-3  # m, stage position of first touch


def approach_and_hold(compliance=0.0, seed=9, depth=D):
    """A plate record as a ramp_hold step stores it: a tare clear of the sphere, a stage ramp
    that starts 0.1 mm before touch and stops ``depth`` past it, the hold. With a load cell of
    ``compliance`` (m/N) the overlap is the stage travel less its deflection."""
    dt = 0.01
    n_pre, n_ramp = round(0.1e-3 / V / dt), round(depth / V / dt)
    t = dt * np.arange(-100 - n_pre, n_ramp + round(HOLD / dt) + 1)
    travel = np.clip(V * t, -0.1e-3, depth)  # stage position less TOUCH
    force = np.zeros_like(t)
    for _ in range(4):  # the deflection feeds back on the overlap: a few fixed-point steps
        overlap = np.maximum(travel - compliance * force, 0.0)
        force = normal_force(t - t[0], overlap, paper.PLATES, R)
    force = force + np.random.default_rng(seed).normal(0.0, NOISE, force.size)
    return t, force, TOUCH + travel


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_first_touch_is_refitted_on_the_ramp(seed):
    late = TOUCH + 3.4e-6  # the contact search: 3.4 um late, so the plate went
    t, force, position = approach_and_hold(seed=seed, depth=D + 3.4e-6)  # 3.4 um deeper
    nominal = analyse_hold(t, force, position - late, R, D, terms=(1,))
    measured = analyse_hold(t, force, position - late, R, D, terms=(1,), position=position)
    assert measured.overlap is not None and measured.overlap.touch is not None
    assert measured.overlap.recorded_touch == pytest.approx(late, abs=1e-9)
    assert measured.overlap.first_touch == pytest.approx(TOUCH, abs=1e-6)
    assert measured.overlap.held == pytest.approx(D + 3.4e-6, abs=1e-6)
    assert nominal.fits[0].g_e > paper.PLATES.g_e * 1.003  # the nominal depth: too stiff
    assert measured.fits[0].g_e == pytest.approx(paper.PLATES.g_e, rel=0.002)


def test_the_load_cells_deflection_is_taken_off_the_plate_travel():
    compliance = 1e-4  # m/N: 15 um at the hold's 0.15 N
    t, force, position = approach_and_hold(compliance)
    delta = position - TOUCH
    ignored = analyse_hold(t, force, delta, R, D, terms=(1,), position=position)
    held = analyse_hold(t, force, delta, R, D, terms=(1,), position=position,
                        compliance=compliance)
    t0, force0, position0 = approach_and_hold(0.0)  # the same noise on a stiff load cell
    stiff = analyse_hold(t0, force0, position0 - TOUCH, R, D, terms=(1,), position=position0)
    assert held.overlap is not None and held.overlap.compliance == compliance
    assert held.overlap.first_touch == pytest.approx(TOUCH, abs=1e-6)
    assert held.overlap.held == pytest.approx(D - compliance * force[-1], abs=1e-6)
    assert held.fits[0].g_e == pytest.approx(stiff.fits[0].g_e, rel=5e-4)
    assert ignored.fits[0].g_e < stiff.fits[0].g_e * 0.995  # travel overstates the overlap


def test_without_a_ramp_to_fit_the_recorded_touch_is_kept(record):
    _, t, force, delta = record  # the model's record starts at touch: no baseline before it
    out = analyse_hold(t, force, delta, R, D, terms=(1,), position=TOUCH + delta)
    assert out.overlap is not None
    assert out.overlap.first_touch == pytest.approx(TOUCH, abs=2e-6)


def test_measured_overlap_without_a_ramp_or_with_gaps_keeps_going():
    _, force, position = approach_and_hold()
    delta = position - TOUCH
    none, overlap = measured_overlap(position, force, delta, 0)
    assert none.touch is None and none.why == "no ramp before the hold"
    assert none.first_touch == pytest.approx(TOUCH) and overlap == pytest.approx(delta)
    start = int(np.argmax(delta >= D - 1e-12))
    gappy = force.copy()
    gappy[start - 500:start - 490] = np.nan  # an over-range burst on the ramp
    found, _ = measured_overlap(position, gappy, delta, start)
    assert found.touch is not None and found.first_touch == pytest.approx(TOUCH, abs=1e-6)


def test_measured_overlap_leaves_flagged_positions_out_of_the_refit():
    _, force, position = approach_and_hold()
    delta = position - TOUCH
    start = int(np.argmax(delta >= D - 1e-12))
    wrong = force.copy()
    bad = slice(start - 400, start - 200)
    wrong[bad] += 5e-3  # samples whose plate position was wrong (flagged, issue 24)
    trusted = np.ones(position.size, dtype=bool)
    trusted[bad] = False
    kept, _ = measured_overlap(position, wrong, delta, start, trusted=trusted)
    assert kept.first_touch == pytest.approx(TOUCH, abs=1e-6)
    used, _ = measured_overlap(position, wrong, delta, start)
    assert abs(used.first_touch - TOUCH) > 2e-6
