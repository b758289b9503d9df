"""Warnings where the shear ladder's per-pass recipe is known to be biased (issue 26)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from gelrig.instrument.analysis.model_fit import Estimate
from gelrig.instrument.reports.ladder import ladder_warnings, touch_gap_stderr


def _ladder(overlap: float = 0.38e-3) -> SimpleNamespace:
    return SimpleNamespace(analysis=SimpleNamespace(results=[SimpleNamespace(overlap=overlap)]))


def _fit(g_h: tuple[float, float, float], g_v: tuple[float, float, float]) -> SimpleNamespace:
    est = {e.name: e for e in (Estimate("G_1_h", g_h[0], math.nan, g_h[1], g_h[2], "Pa"),
                               Estimate("G_1_v", g_v[0], math.nan, g_v[1], g_v[2], "Pa"))}
    return SimpleNamespace(estimates=tuple(est.values()), estimate=est.__getitem__, mu=0.005)


def _search(gap0: float = 3e-3, jitter: float = 0.0) -> dict[str, object]:
    gaps = [2.3e-3, 2.25e-3, 2.2e-3]
    root = [(gap0 - g) * 0.015 * (1 + j) for g, j in zip(gaps, (0.0, jitter, -jitter))]
    return {"touch_fit": {"gaps_m": gaps, "peak_torque_Nm": [r * r for r in root]}}


def test_mu_from_the_force_ratio_warns_when_the_fit_tells_f_h_and_f_v_apart():
    apart = ladder_warnings(_ladder(), _fit((2e4, 1.98e4, 2.02e4), (1.6e4, 1.58e4, 1.62e4)))
    assert len(apart) == 1 and "mu = F_h/F_v at the centre of l_g is biased" in apart[0]
    assert ladder_warnings(_ladder(), _fit((2e4, 1.9e4, 2.1e4), (2e4, 1.9e4, 2.1e4))) == []
    assert ladder_warnings(_ladder(), None) == []


def test_touch_gap_standard_error_and_the_overlap_warning():
    assert touch_gap_stderr(_search()) == pytest.approx(0.0, abs=1e-12)
    se = touch_gap_stderr(_search(jitter=0.001))  # 0.1 % on the roots, 0.7 mm extrapolated
    assert 1e-6 < se < 1e-4 and np.isfinite(se)
    assert ladder_warnings(_ladder(), None, _search(jitter=0.001)) == []
    (line,) = ladder_warnings(_ladder(), None, _search(jitter=0.01))
    assert "the smallest overlap (0.380 mm) is within 10x the touch gap's standard error" in line
    assert math.isnan(touch_gap_stderr({}))
