"""The GUI's live-fit panel: G(t) with the running fit and its band, and the fit history."""

from __future__ import annotations

import numpy as np
import pytest

from gelrig.gui.fit_panel import BAND, FitPanel, summary
from gelrig.instrument.analysis.live_fit import StopRule
from gelrig.instrument.analysis.live_fit_sim import simulate_hold
from gelrig.instrument.physics import paper
from gelrig.protocols.events import FitUpdate, StepStarted


@pytest.fixture(scope="module")
def updates() -> list[FitUpdate]:
    rule = StopRule(0.02, terms=2)
    sim = simulate_hold(paper.SHELL, 2, 3000.0, 100.0, seed=11, rule=rule)
    out = []
    for i, state in enumerate(sim.history):
        done = rule.done(sim.history[:i + 1])
        out.append(FitUpdate(state.elapsed, 1, state, rule.met(state), done))
    return out


def test_panel_draws_the_fit_its_band_and_the_history(qtbot, updates) -> None:
    panel = FitPanel()
    qtbot.addWidget(panel)
    panel.on_event(StepStarted(0.0, 1, "hold", "ramp_hold", {}, {}))
    for event in updates:
        panel.on_event(event)
    last = updates[-1].state
    assert panel.points() == len(updates)
    _t, g, sd = last.curve
    assert np.array_equal(panel.fit_curve.yData, g)
    assert np.allclose(panel.band_hi.yData - panel.band_lo.yData, 2 * BAND * sd)
    assert panel.points_item.xData.size == last.data[0].size
    # one history curve per time constant; tau_2 only from the refits that had two terms
    assert len(panel.taus) == 2
    assert panel.taus[0].xData.size == len(updates)
    assert panel.taus[1].yData[-1] == last.relax[1].tau
    assert panel.stop.isVisible() and panel.stop.value() == last.elapsed
    assert panel.line.text().startswith("adaptive hold ends: ")
    assert "2 terms resolved" in panel.line.text()
    panel.on_event(StepStarted(1.0, 2, "hold again", "ramp_hold", {}, {}))
    assert panel.points() == 0 and not panel.stop.isVisible()


def test_summary_says_tau_its_uncertainty_and_terms(updates) -> None:
    line = summary(updates[-1])
    st = updates[-1].state
    assert f"tau_1 {st.relax[0].tau:.4g} s +- {st.relative['tau_1'] * 100:.2g} %" in line
    assert "target met" in line
