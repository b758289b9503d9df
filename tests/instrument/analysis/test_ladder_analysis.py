"""A speed-ladder step analysed whole, on the synthetic recorded ladder of test_shear_analysis."""

import math

import numpy as np
import pytest

from gelrig.instrument.analysis.ladder_analysis import analyse_ladder_step, fit_ladder_model
from gelrig.instrument.analysis.model_fit import FitSetup
from gelrig.instrument.analysis.shear_analysis import RecordedPass, analyse_ladder, geometric_l_g
from gelrig.instrument.core.errors import ConfigError
from tests.instrument.analysis.test_shear_analysis import (
    ARM,
    LOWER,
    MU,
    R1,
    R2,
    TOUCH,
    synth_ladder,
)

S = R1 + R2


@pytest.fixture(scope="module")
def columns():
    return synth_ladder(overlaps=(0.5e-3,), speeds=(4.75e-5, 2.37e-4), seed=3)[0]


@pytest.fixture(scope="module")
def step(columns):
    return analyse_ladder_step(columns, ARM, travel=14e-3)


def test_passes_results_and_forces_line_up(columns, step):
    analysis, passes = analyse_ladder(columns, ARM, travel=14e-3)
    assert step.analysis == analysis
    assert [p.index for p in step.passes] == [r.index for r in step.analysis.results] \
        == [p.index for p in passes] == [0, 1, 2, 3]
    assert sorted(step.forces) == [0, 1, 2, 3]
    for p in step.passes:
        assert step.forces[p.index].theta == pytest.approx(p.angle * ARM)


def test_levels_without_a_fit_have_no_geometric_l_g(step):
    rows = step.levels()
    assert len(rows) == 2
    assert all(math.isnan(r["l_g_geom_m"]) for r in rows)
    assert [r["mu"] for r in rows] == [r["mu"] for r in step.analysis.levels()]


def _pass(gap, overlap=5e-4, speed=1e-4):
    n = 40
    z = np.zeros(n)
    return RecordedPass(0, 1.0, speed, overlap, z, z, z, z, np.full(n, gap))


def test_geometric_l_g_is_the_chord_at_the_recorded_gap(step):
    touch, gap = 3e-3, 2.6e-3  # 0.4 mm overlap from the recorded gap
    r = step.analysis.results[0]
    p = _pass(gap, r.overlap, r.speed)
    h = S - 0.4e-3
    expect = 2 * math.sqrt(S**2 - h**2)
    assert geometric_l_g(S, touch, [p], [r], round(r.overlap, 9), r.speed) == \
        pytest.approx(expect, rel=1e-12)
    # no pass at that level, and the spheres apart: no length
    assert math.isnan(geometric_l_g(S, touch, [p], [r], 1.0, r.speed))
    assert geometric_l_g(S, gap - 1e-4, [p], [r], round(r.overlap, 9), r.speed) == 0.0


def test_model_fit_over_the_history(columns, step):
    setup = FitSetup(R1, R2, ARM)
    model = fit_ladder_model(step, [columns], setup, TOUCH + 5e-6, LOWER - 3e-4)
    assert model.fit.mu == pytest.approx(MU, rel=0.05)
    assert model.f_h.shape == model.f_v.shape == (len(model.trajectory),)
    assert len(model.trajectory) == columns["t_s"].size
    rows = step.levels(model.fit, S)
    for row in rows:
        chord = 2 * math.sqrt(S**2 - (S - row["overlap_m"]) ** 2)
        assert row["l_g_geom_m"] == pytest.approx(chord, rel=0.01)
    with pytest.raises(ConfigError):
        fit_ladder_model(step, [columns], setup, math.nan, LOWER)
