"""The CLI's progress line during a hold shows the live fit; an adaptive hold's end is said."""

from __future__ import annotations

import io

from rich.console import Console

from gelrig.console import ConsoleView, fit_line
from gelrig.instrument.analysis.live_fit import StopRule
from gelrig.instrument.analysis.live_fit_sim import simulate_hold
from gelrig.instrument.physics import paper
from gelrig.protocols.events import FitUpdate, Progress, StepFinished, StepStarted


def test_progress_line_shows_tau_its_uncertainty_and_terms_and_the_end() -> None:
    sim = simulate_hold(paper.PLATES, 1, 3000.0, 100.0, seed=4, rule=StopRule(0.02))
    state = sim.history[-1]
    out = io.StringIO()
    view = ConsoleView(Console(file=out, width=250, force_terminal=False))
    with view:
        view(StepStarted(0.0, 0, "hold", "ramp_hold", {}, {}))
        view(FitUpdate(state.elapsed, 0, state, met=True, ending=True))
        view(Progress(state.elapsed, 0, 0.3, state.elapsed, 2000.0, "hold"))
        line = fit_line(FitUpdate(state.elapsed, 0, state, met=True))
        assert line.startswith(f"tau {state.tau:.4g} s +- {state.tau_relative * 100:.2g} %")
        assert "1 term resolved" in line and "target met" in line
        assert view.progress.tasks[0].fields["live"] == f"hold; {line}"
        view(StepFinished(state.elapsed, 0, "hold", "completed",
                          {"hold_end": "target", "held_s": sim.ended}))
    text = out.getvalue()
    assert f"adaptive hold ended after {sim.ended:.0f} s (target met)" in text
