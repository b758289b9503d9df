"""The hold's report layer: problems, table rows and summary lines from a HoldAnalysis."""

import math

import numpy as np

from instrument.analysis import RelaxationFit
from instrument.contact import RelaxationTerm
from instrument.hold import HoldSpan
from instrument.hold_analysis import HoldAnalysis
from instrument.report_hold import fit_rows, hold_problems, hold_section, hold_summary

FIT = RelaxationFit(7000.0, (RelaxationTerm(600.0, 1400.0),), 30.0, 20.0,
                    {"G_e": 10.0, "G_1": 12.0, "tau_1": 40.0}, 1000)


def analysis(duration=300.0, planned=600.0, fits=(FIT,), errors=None):
    t = np.linspace(0.0, duration, 1000)
    return HoldAnalysis(HoldSpan(100, 1100, 1.1e-3), 4.5e-3, 1.1e-3, duration, planned, t,
                        FIT.model(t), fits, errors or {})


def test_problems_name_a_short_hold_and_failed_fits():
    out = hold_problems(analysis(errors={2: "no convergence"}), 1, "hold")
    assert out == ["step 1 (hold): hold recorded for 300 s of the planned 600 s; fitting that",
                   "step 1: 2-term fit failed (no convergence)"]
    assert hold_problems(analysis(duration=600.0), 1, "hold") == []


def test_fit_rows_one_per_parameter():
    rows = fit_rows((FIT,))
    assert [(r["parameter"], r["value"], r["stderr"]) for r in rows] == [
        ("G_e", 7000.0, 10.0), ("G_1", 600.0, 12.0), ("tau_1", 1400.0, 40.0)]
    assert all(r["terms"] == 1 and r["rmse_Pa"] == 20.0 for r in rows)


def test_summary_and_section(tmp_path):
    hold = analysis()
    lines = hold_summary(hold, 1, "hold")
    assert lines[0] == "Hold, step 1 (hold): 300 s, 1000 samples, delta 1.100 mm"
    assert lines[1].startswith("  1-term: G_e 7000 +- 10 Pa; G_1 600 +- 12 Pa, tau_1 1400")
    section = hold_section(hold, 1, "hold", tmp_path)
    assert (tmp_path / "hold_01.png").stat().st_size > 5000
    fits, residuals = section.tables
    assert fits.csv_name == "hold_01_fits.csv" and len(residuals.rows) == 300
    # a noiseless G(t) of the fitted model: only the curvature within a bin is left
    assert max(abs(float(r["residual_1_Pa"])) for r in residuals.rows) < 1e-3
    assert not math.isnan(float(residuals.rows[0]["G_Pa"]))


def _live_results():
    from instrument import paper
    from instrument.live_fit import StopRule
    from instrument.live_fit_sim import simulate_hold

    sim = simulate_hold(paper.PLATES, 1, 3000.0, 100.0, seed=4, rule=StopRule(0.02))
    results = {"live_fits": [s.as_dict() for s in sim.history], "hold_end": sim.reason,
               "held_s": sim.ended}
    return sim, results, {"hold": 3000.0, "until": 0.02, "until_terms": 1}


def test_summary_and_section_keep_the_live_fit_and_how_the_hold_ended(tmp_path):
    sim, results, params = _live_results()
    lines = hold_summary(analysis(), 1, "hold", results, params)
    end = next(line for line in lines if "adaptive hold" in line)
    assert f"after {sim.ended:.0f} s of at most 3000 s" in end
    assert f"{len(sim.history)} refits" in end
    section = hold_section(analysis(), 1, "hold", tmp_path, results, params)
    live = section.tables[-1]
    assert len(live.rows) == len(sim.history)
    assert [r["elapsed_s"] for r in live.rows] == [s.elapsed for s in sim.history]
    assert live.rows[-1]["tau_1_s"] == sim.history[-1].tau
    assert any("Adaptive hold ended on its target" in p for p in section.paragraphs)


def test_a_run_without_a_live_fit_reports_as_before(tmp_path):
    assert hold_summary(analysis(), 1, "hold", {}, {}) == hold_summary(analysis(), 1, "hold")
    assert len(hold_section(analysis(), 1, "hold", tmp_path, {}, {}).tables) == 2
