"""The hold's report layer: problems, table rows and summary lines from a HoldAnalysis."""

import math

import numpy as np

from gelrig.instrument.analysis.hold import HoldSpan
from gelrig.instrument.analysis.hold_analysis import HoldAnalysis
from gelrig.instrument.analysis.relaxation import RelaxationFit
from gelrig.instrument.physics.contact import RelaxationTerm
from gelrig.instrument.reports.hold import fit_rows, hold_problems, hold_section, hold_summary

FIT = RelaxationFit(7000.0, (RelaxationTerm(600.0, 1400.0),), 30.0, 20.0,
                    {"G_e": 10.0, "G_1": 12.0, "tau_1": 40.0}, 1000, terms_resolved=1)
#: Two terms asked, the second not resolved (as fit_relaxation reports it).
TWO = RelaxationFit(7000.0, (RelaxationTerm(600.0, 1400.0), RelaxationTerm(50.0, 900.0)), 30.0,
                    19.9, {"G_e": 10.0, "G_1": 12.0, "tau_1": 40.0, "G_2": math.nan,
                           "tau_2": math.nan}, 1000, terms_resolved=1,
                    not_resolved="second term not resolved: BIC improvement 2.1 < 10")
#: A 60 s hold: not even one term resolved.
NONE = RelaxationFit(7772.0, (RelaxationTerm(54.0, 104.0),), 0.0, 20.0,
                     {"G_e": 3.0, "G_1": 40.0, "tau_1": 150.0}, 6000, terms_resolved=0,
                     not_resolved="first term not resolved: BIC improvement 4 < 10")


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


def test_an_unresolved_fit_is_no_result(tmp_path):
    """Summary, table and CSV say "not resolved: <reason>" and carry no values for a fit the
    data do not resolve; ``resolved`` is a true/false column with the reason beside it."""
    from gelrig.instrument.reports.document import write_csv

    lines = hold_summary(analysis(fits=(FIT, TWO)), 1, "hold")
    assert lines[1].startswith("  1-term: G_e 7000 +- 10 Pa")
    assert lines[2] == ("  2-term: not resolved: second term not resolved: BIC improvement "
                        "2.1 < 10")
    assert hold_summary(analysis(fits=(NONE,)), 1, "hold")[1] == (
        "  1-term: not resolved: first term not resolved: BIC improvement 4 < 10")
    rows = fit_rows((FIT, TWO))
    assert [r["resolved"] for r in rows] == [True] * 3 + [False] * 5
    assert all(r["value"] is None and r["stderr"] is None and "BIC" in str(r["reason"])
               for r in rows[3:])
    section = hold_section(analysis(fits=(FIT, TWO)), 1, "hold", tmp_path)
    path = write_csv(tmp_path / "fits.csv", section.tables[0])
    text = path.read_text().splitlines()
    assert text[0].split(",")[-2:] == ["resolved", "reason"]
    assert text[1].split(",")[-2:] == ["true", ""]
    assert text[4].split(",")[2:4] == ["", ""] and ",false,second term not resolved" in text[4]
    assert any("2-term fit: not resolved: second term" in p for p in section.paragraphs)


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
    from gelrig.instrument.analysis.live_fit import StopRule
    from gelrig.instrument.analysis.live_fit_sim import simulate_hold
    from gelrig.instrument.physics import paper

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


def test_a_hold_shorter_than_its_fitted_tau_or_near_the_resolution_warns():
    from gelrig.instrument.reports.hold import hold_warnings

    short = analysis(duration=60.0, planned=60.0, fits=(NONE,))
    (line,) = [w for w in hold_summary(short, 1, "hold") if "WARNING" in w]
    assert "the hold (60 s) is shorter than the fitted tau (104 s)" in line
    assert hold_warnings(analysis(duration=3000.0, planned=3000.0)) == []
    near = hold_warnings(analysis(duration=3000.0, planned=3000.0), resolution=0.1e-3)
    assert len(near) == 1 and "within 20x the resolution of first touch (1e+02 um)" in near[0]


def test_an_unrefitted_touch_warns_by_the_contact_searchs_spread():
    """First touch not refitted on the ramp (no standard error): the search's spread stands
    for its resolution (issue 26 item 4: a 4 um overlap on a 1 um search did not warn)."""
    from gelrig.instrument.reports.hold import hold_warnings

    hold = analysis(duration=3000.0, planned=3000.0)
    assert hold.overlap is None
    (near,) = hold_warnings(hold, search_spread=0.1e-3)
    assert "within 20x the resolution of first touch (1e+02 um)" in near
    assert hold_warnings(hold, search_spread=1e-9) == []
