"""Per-pass quantities of a ladder (l_c, l_g, mu, zero offset) on synthetic recorded passes.

``synth_ladder`` is a small stand-in for the rig: it drives one NormalContact through a
ladder's whole motion (so each pass meets the history of the earlier ones, as in the
simulator), resolves the forces with friction, and records them as the ladder step would:
lab torque with bearing drag and noise, normal force with noise, 0.1 s samples.
"""

import math

import numpy as np
import pytest

from gelrig.instrument.analysis.shear_analysis import (
    RecordedPass,
    analyse_ladder,
    analyse_pass,
    chord,
    pass_forces,
    split_passes,
    value_at,
    with_chords,
)
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import Material, NormalContact, effective_radius
from gelrig.instrument.physics.sliding import resolve_forces

ARM = 0.027
R1, R2 = 9.2e-3, 9.96e-3
TRUTH = Material.of(4e3, [(2e4, 2000.0)])
MU = 5e-3
TOUCH = 3e-3
LOWER = 0.8
DRAG = 2e-6  # N m, in the direction of motion
NOISE_M = 1e-7  # N m
NOISE_N = 2e-5  # N


def synth_ladder(overlaps=(0.5e-3,), speeds=(4.75e-5, 2.37e-4), travel=14e-3, wait=60.0,
                 dt=0.1, seed=1, material=TRUTH, mu=MU, t_start=0.0, material_vertical=None,
                 carry_history=False):
    """Columns of a recorded speed ladder (the recorder's names), and the true per-sample
    moving-frame F_h and F_v (F_v from ``material_vertical`` if given)."""
    half = travel / 2 / ARM
    start, end = LOWER - half, LOWER + half
    parts = []  # (t, angle, gap, pass, direction, speed, overlap)
    t = t_start
    k = 0

    def segment(n, angle, gap, label, direction, speed, overlap):
        nonlocal t
        times = t + dt * np.arange(1, n + 1)
        t = float(times[-1])
        parts.append((times, angle, np.full(n, gap), np.full(n, label), np.full(n, direction),
                      np.full(n, speed), np.full(n, overlap)))

    for depth in overlaps:
        gap = TOUCH - depth
        segment(50, np.full(50, start), gap, -1.0, 0.0, 0.0, math.nan)  # lowered, at rest
        for v in speeds:
            for direction, (a, b) in ((1.0, (start, end)), (-1.0, (end, start))):
                n = round(travel / v / dt)
                angle = a + (b - a) * np.arange(1, n + 1) / n
                segment(n, angle, gap, float(k), direction, v, depth)
                rest = round(wait / dt)
                segment(rest, np.full(rest, b), gap, -1.0, 0.0, 0.0, math.nan)
                k += 1
    cols = [np.concatenate(c) for c in zip(*parts)]
    t_s, angle, gap, label, direction, speed, overlap = cols
    s = R1 + R2
    x = (angle - LOWER) * ARM
    h = s - (TOUCH - gap)
    delta = s - np.hypot(h, x)
    radius = effective_radius(R1, R2)
    f_perp = NormalContact(material, radius, carry_history=carry_history).block(t_s, delta)
    f_perp_v = f_perp if material_vertical is None else NormalContact(
        material_vertical, radius, carry_history=carry_history).block(t_s, delta)
    frame = np.where(direction == 0, 1.0, direction)
    psi = -frame * x / h
    f_h, _ = resolve_forces(f_perp, psi, 1.0, 0.0)
    _, f_v = resolve_forces(f_perp_v, psi, 1.0, 0.0)
    moving = direction != 0
    f_h[moving] = resolve_forces(f_perp[moving], psi[moving], 1.0, mu)[0]
    f_v[moving] = resolve_forces(f_perp_v[moving], psi[moving], 1.0, mu)[1]
    rng = np.random.default_rng(seed)
    torque = frame * f_h * ARM + direction * DRAG + rng.normal(0, NOISE_M, t_s.size)
    normal = f_v + rng.normal(0, NOISE_N, t_s.size)
    columns = {"t_s": t_s, "angle_rad": angle, "theta_m": angle * ARM, "torque_Nm": torque,
               "normal_force_N": normal, "gap_m": gap, "pass": label, "direction": direction,
               "speed_m_s": speed, "overlap_m": overlap}
    return columns, f_h, f_v


@pytest.fixture(scope="module")
def ladder():
    return synth_ladder(overlaps=(0.4e-3, 0.7e-3), speeds=(2.38e-5, 1.19e-4, 2.37e-4))


def test_split_and_baseline_remove_drag_and_measure_noise(ladder):
    cols, f_h_true, _ = ladder
    passes = split_passes(cols)
    assert [p.index for p in passes] == list(range(12))
    assert [p.direction for p in passes[:2]] == [1.0, -1.0]
    for p in passes[:2]:
        f = pass_forces(p, ARM)
        assert f.torque_baseline == pytest.approx(p.direction * DRAG, abs=3 * NOISE_M)
        assert f.noise_h == pytest.approx(NOISE_M / ARM, rel=0.15)
        assert f.noise_v == pytest.approx(NOISE_N, rel=0.15)
        true_h = f_h_true[cols["pass"] == p.index]
        assert np.std(f.f_h - true_h) == pytest.approx(NOISE_M / ARM, rel=0.15)


def test_contact_lengths_follow_the_paper(ladder):
    cols, _, _ = ladder
    analysis, _ = analyse_ladder(cols, ARM, travel=14e-3)
    assert analysis.problems == []
    s = R1 + R2
    for row in analysis.levels():
        geometric = 2 * math.sqrt(s**2 - (s - row["overlap_m"]) ** 2)
        assert row["l_c_C_m"] < row["l_g_m"] and row["l_c_AC_m"] < row["l_g_m"]
        # each pass a fresh contact, first touch extrapolated to zero force: l_g is the chord
        assert row["l_g_m"] == pytest.approx(geometric, rel=5e-3)
    for overlap in {r["overlap_m"] for r in analysis.levels()}:
        ratios = [r["l_c_over_l_g"] for r in analysis.levels() if r["overlap_m"] == overlap]
        assert all(np.diff(ratios) > 0), ratios  # rises with speed (speeds ascend)
        assert ratios[-1] < 1.0


def test_mu_and_zero_offset_recovered(ladder):
    cols, _, _ = ladder
    analysis, _ = analyse_ladder(cols, ARM)
    s = R1 + R2
    for row in analysis.levels():
        assert row["mu"] == pytest.approx(0.5 * (row["mu_C"] + row["mu_AC"]))
        assert row["mu"] == pytest.approx(MU, rel=0.05)  # issue: within 20 %
        h = s - row["overlap_m"]
        assert row["zero_offset_m"] == pytest.approx(MU * h, rel=0.1)
    # the peak (approach) exceeds the trough (departure) in magnitude
    for r in analysis.results:
        assert r.f_h_peak > -r.f_h_trough > 0


def test_frictionless_passes_give_zero_mu():
    cols, _, _ = synth_ladder(speeds=(2.37e-4,), mu=0.0)
    analysis, _ = analyse_ladder(cols, ARM)
    (row,) = analysis.levels()
    assert abs(row["mu"]) < 2e-4
    assert abs(row["zero_offset_m"]) < 5e-6
    # per pass, the centre's error shows with opposite signs in C and AC
    c, ac = analysis.results
    assert c.mu == pytest.approx(-ac.mu, abs=2e-4)


def test_truncated_and_unpaired_passes_are_reported():
    cols, _, _ = synth_ladder(speeds=(2.37e-4,))
    last = np.flatnonzero(cols["pass"] == 1)
    cut = int(last[len(last) // 3])
    short = {k: v[:cut] for k, v in cols.items()}
    analysis, good = analyse_ladder(short, ARM, travel=14e-3)
    assert [p.index for p in good] == [0]
    assert any("pass 1 is truncated" in p for p in analysis.problems)
    assert any("no opposite pass" in p and "0" in p for p in analysis.problems)
    assert math.isnan(analysis.results[0].l_g)
    assert analysis.results[0].l_c > 0


def test_pass_without_contact_raises_with_a_reason():
    cols, _, _ = synth_ladder(overlaps=(0.4e-3,), speeds=(2.37e-4,))
    p = split_passes(cols)[0]
    flat = RecordedPass(p.index, p.direction, p.speed, p.overlap, p.t, p.angle,
                        np.random.default_rng(2).normal(DRAG, NOISE_M, p.t.size),
                        np.random.default_rng(3).normal(0, NOISE_N, p.t.size), p.gap)
    with pytest.raises(ConfigError, match="never rose"):
        analyse_pass(flat, ARM)


def test_pass_starting_in_contact_has_no_baseline():
    cols, _, _ = synth_ladder(overlaps=(0.7e-3,), speeds=(2.37e-4,), travel=10.5e-3)
    with pytest.raises(ConfigError, match="clear of contact"):
        analyse_pass(split_passes(cols)[0], ARM)


def test_missing_columns_are_named():
    cols, _, _ = synth_ladder(speeds=(2.37e-4,))
    del cols["torque_Nm"]
    with pytest.raises(ConfigError, match="torque_Nm"):
        split_passes(cols)


def test_value_at_is_exact_on_a_parabola_either_direction():
    x = np.linspace(-1e-3, 1e-3, 201)
    y = 3.0 + 2e3 * x - 5e6 * x**2
    assert value_at(x, y, 1e-4) == pytest.approx(3.0 + 0.2 - 0.05, rel=1e-9)
    assert value_at(x[::-1], y[::-1], 1e-4) == pytest.approx(3.0 + 0.2 - 0.05, rel=1e-9)


def test_the_chord_is_the_geometric_contact_length_at_the_overlap():
    r1, r2 = paper.R1_SHEAR, paper.R2_SHEAR
    s = r1 + r2
    for overlap in (0.38e-3, 0.78e-3):
        assert chord(r1, r2, overlap) == pytest.approx(
            2 * math.sqrt(s**2 - (s - overlap) ** 2), rel=1e-12)
    assert math.isnan(chord(r1, r2, 0.0)) and math.isnan(chord(r1, r2, 2 * s))
    rows = with_chords([{"overlap_m": 0.78e-3, "l_g_m": 0.0108},
                        {"overlap_m": 0.78e-3, "l_g_m": math.nan}], r1, r2)
    c = chord(r1, r2, 0.78e-3)
    assert rows[0]["l_g_chord_m"] == c and rows[0]["l_g_over_chord"] == pytest.approx(0.0108 / c)
    assert math.isnan(rows[1]["l_g_over_chord"])


def test_both_edges_come_from_the_whole_pass_profile(ladder):
    """docs/decisions/0260 addendum: every pass's touch and detachment are refined by the fit
    of its whole in-contact profile, and its l_c is the fresh-contact model's within its
    standard error and 1 um (the three-term shape at the slowest speed)."""
    from gelrig.instrument.physics.sliding import SlidingGeometry, shear_pass

    cols, _, _ = ladder
    analysis, _ = analyse_ladder(cols, ARM, travel=14e-3)
    for r in analysis.results:
        assert r.edges == "profile", r.edges_note
        sp = shear_pass(SlidingGeometry(R1, R2, r.overlap), TRUTH, r.speed, MU,
                        dt=1e-7 / r.speed)
        inside = np.flatnonzero(sp.f_perp > 0)
        model = float(sp.theta[inside[-1]] - sp.theta[inside[0]])
        assert 0 < r.l_c_stderr < 3e-6
        assert r.l_c == pytest.approx(model, abs=4 * r.l_c_stderr + 1e-6), r.index


def test_a_carried_history_keeps_the_local_edges_and_says_why():
    """A pass that is not a fresh contact does not have the profile's shape: the pair keeps
    the edges of the local fits, and ``edges_note`` gives the reason."""
    cols, _, _ = synth_ladder(carry_history=True)
    analysis, _ = analyse_ladder(cols, ARM, travel=14e-3)
    for r in analysis.results:
        assert r.edges == "local" and r.edges_note, (r.index, r.edges_note)
        assert r.l_c == pytest.approx(r.local_l_c, abs=1e-12)
