"""The six features of physics.md section 5, at the paper's parameters."""

import itertools
import math

import numpy as np
import pytest

from gelrig.instrument.analysis.relaxation import contact_length, fit_hold
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.sliding import (
    SlidingGeometry,
    resolve_forces,
    rpm_from_speed,
    shear_pass,
    speed_from_rpm,
)

GEOMETRY = SlidingGeometry(paper.R1_SHEAR, paper.R2_SHEAR, paper.DELTA_MAX_SHOWN)


@pytest.fixture(scope="module")
def passes():
    return {v: shear_pass(GEOMETRY, paper.SHEAR_FH, v, paper.MU, margin=1e-4)
            for v in paper.SPEEDS}


@pytest.fixture(scope="module")
def vertical_passes():
    return {v: shear_pass(GEOMETRY, paper.SHEAR_FV, v, paper.MU, margin=1e-4)
            for v in paper.SPEEDS}


def test_geometry():
    s = paper.R1_SHEAR + paper.R2_SHEAR
    assert GEOMETRY.h == pytest.approx(s - 0.78e-3)
    assert GEOMETRY.psi0 == pytest.approx(math.sqrt(s**2 - GEOMETRY.h**2))
    assert GEOMETRY.overlap(0.0) == pytest.approx(0.78e-3)
    assert GEOMETRY.overlap(GEOMETRY.psi0) == pytest.approx(0.0, abs=1e-15)
    assert GEOMETRY.l_g == pytest.approx(2 * GEOMETRY.psi0)


def test_feature1_peak_larger_than_trough(passes):
    for sp in passes.values():
        assert sp.f_h.max() > 0 > sp.f_h.min()
        assert sp.f_h.max() > abs(sp.f_h.min()) * 1.05


def test_feature2_trough_and_peak_grow_with_speed(passes):
    troughs = [abs(passes[v].f_h.min()) for v in paper.SPEEDS]
    peaks = [passes[v].f_h.max() for v in paper.SPEEDS]
    assert all(b > a for a, b in itertools.pairwise(troughs))
    assert all(b > a for a, b in itertools.pairwise(peaks))
    # The trough depends on speed more strongly than the peak.
    assert troughs[-1] / troughs[0] > peaks[-1] / peaks[0]


def test_feature3_contact_length_shorter_than_geometric_and_growing(passes):
    ratios = [contact_length(passes[v].theta, passes[v].f_perp) / GEOMETRY.l_g
              for v in paper.SPEEDS]
    assert all(0.5 < r < 1.0 for r in ratios)
    assert all(b > a for a, b in itertools.pairwise(ratios))


def test_feature4_friction_offset_on_top_and_shifted_zero_crossing(passes):
    sp = passes[paper.SPEEDS[0]]
    top = int(np.argmin(np.abs(sp.psi)))
    assert sp.f_h[top] == pytest.approx(paper.MU * sp.f_perp[top], rel=1e-3)
    inside = sp.f_perp > 0
    psi, f_h = sp.psi[inside], sp.f_h[inside]
    k = int(np.flatnonzero(np.diff(np.sign(f_h)) < 0)[0])
    crossing = psi[k] - f_h[k] * (psi[k + 1] - psi[k]) / (f_h[k + 1] - f_h[k])
    assert crossing < 0  # towards detachment
    assert crossing == pytest.approx(-paper.MU * GEOMETRY.h, rel=0.02)
    # Without friction it crosses on top.
    frictionless = shear_pass(GEOMETRY, paper.SHEAR_FH, paper.SPEEDS[0], 0.0, margin=1e-4)
    j = int(np.argmin(np.abs(frictionless.psi)))
    assert abs(frictionless.f_h[j]) < 1e-3 * frictionless.f_h.max()


def test_feature4_mirror_direction_shifts_zero_crossing_towards_detachment():
    """A pass the other way: lab offset x runs -psi0 -> +psi0; psi along the motion is -x."""
    sp = shear_pass(GEOMETRY, paper.SHEAR_FH, paper.SPEEDS[1], paper.MU, margin=1e-4)
    x_lab = -sp.psi
    torque_lab = -sp.f_h * paper.ARM  # the lab-frame sign reverses
    inside = sp.f_perp > 0
    x, m = x_lab[inside], torque_lab[inside]
    k = int(np.flatnonzero(np.diff(np.sign(m)) > 0)[0])
    crossing = x[k] - m[k] * (x[k + 1] - x[k]) / (m[k + 1] - m[k])
    assert crossing == pytest.approx(paper.MU * GEOMETRY.h, rel=0.02)  # past the top


def test_feature5_vertical_force_weakly_speed_dependent(vertical_passes):
    peaks = [vertical_passes[v].f_v.max() for v in paper.SPEEDS]
    assert all(b > a for a, b in itertools.pairwise(peaks))
    assert peaks[-1] / peaks[0] < 1.15


def test_feature6_hold_decays_with_material_time_scale():
    rec = ramp_hold(paper.R_COMPRESSION, paper.DEPTH_HOLD, paper.RAMP_SPEED, 3000.0,
                    paper.PLATES, dt=0.1)
    hold = rec.t >= rec.t_hold
    assert np.all(np.diff(rec.force[hold]) < 0)
    fit = fit_hold(rec.t, rec.force, paper.R_COMPRESSION, paper.DEPTH_HOLD)
    assert fit.relax[0].tau == pytest.approx(1413.0, rel=1e-3)
    assert 1000 < fit.relax[0].tau < 2500


def test_resolve_forces_conventions():
    f_h, f_v = resolve_forces(1.0, 0.0, 1.0, 0.1)
    assert f_h == pytest.approx(0.1) and f_v == pytest.approx(1.0)
    f_h, _ = resolve_forces(1.0, 1.0, 1.0, 0.0)
    assert f_h > 0  # approaching: resists
    f_h, _ = resolve_forces(1.0, -1.0, 1.0, 0.0)
    assert f_h < 0  # departing
    with pytest.raises(ConfigError):
        resolve_forces(1.0, 0.0, 1.0, -0.1)


def test_rpm_conversion_and_the_paper_inconsistency():
    rpm = rpm_from_speed(2.38e-5, paper.ARM)
    assert rpm == pytest.approx(8.4e-3, rel=0.01)  # not the paper's 8e-4 rpm
    assert speed_from_rpm(rpm, paper.ARM) == pytest.approx(2.38e-5)


@pytest.mark.parametrize("kwargs", [dict(r1=0.0, r2=1.0, delta_max=0.1),
                                    dict(r1=1.0, r2=1.0, delta_max=2.0),
                                    dict(r1=1.0, r2=1.0, delta_max=-0.1)])
def test_bad_geometry(kwargs):
    with pytest.raises(ConfigError):
        SlidingGeometry(**kwargs)


def test_bad_pass_parameters():
    with pytest.raises(ConfigError, match="speed"):
        shear_pass(GEOMETRY, Material.of(1e3), 0.0)
    with pytest.raises(ConfigError, match="dt"):
        shear_pass(GEOMETRY, Material.of(1e3), 1e-4, dt=-1.0)
