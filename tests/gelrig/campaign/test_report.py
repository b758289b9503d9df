"""The campaign report's figures: coverage, bias, variants, l_c/l_g separation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gelrig.campaign.report import (
    Coverage,
    coverage,
    lclg_by_truth,
    relative_errors,
    variant_rows,
    write_campaign_report,
    z_scores,
)


def _row(i, fit, lo, hi, truth=2000.0, status="ok", variant=None, unloading="cutoff",
         lclg=None):
    return {"member_id": f"m{i}", "index": i, "seed": i, "status": status, "error": "",
            "variant": json.dumps(variant or {}), "truth_variant":
            json.dumps({"unloading": unloading}), "truth.tau_1": truth, "fit.tau_1": fit,
            "se.tau_1": (hi - lo) / 3.92, "lo.tau_1": lo, "hi.tau_1": hi, "wall_s": 1.0,
            "lclg_by_speed": json.dumps(lclg or {})}


def test_coverage_counts_intervals_holding_the_truth_and_undetermined_ones_as_misses():
    rows = [_row(0, 2000, 1900, 2100), _row(1, 2050, 2010, 2090),
            _row(2, 1990, math.nan, math.nan), _row(3, 2000, 1990, 2010),
            _row(4, 0, 0, 0, status="failed")]
    c = coverage(rows, "tau_1")
    assert (c.hits, c.n) == (2, 4)
    lo, hi = c.band()
    assert lo < c.fraction < hi and lo > 0 and hi < 1


def test_the_wilson_band_narrows_with_members():
    small, large = Coverage(19, 20), Coverage(950, 1000)
    assert small.fraction == large.fraction
    assert np.ptp(large.band()) < np.ptp(small.band()) / 5


def test_bias_and_spread_per_variant():
    a = [_row(i, 2000 * (1 + e), 0, 1e9, variant={"step[1].hold": "600 s"})
         for i, e in enumerate((0.01, 0.03))]
    b = [_row(10 + i, 2000 * (1 + e), 0, 1, variant={"step[1].hold": "3000 s"})
         for i, e in enumerate((-0.01, 0.01))]
    np.testing.assert_allclose(sorted(relative_errors(a, "tau_1")), [0.01, 0.03])
    table, names = variant_rows(a + b)
    assert names == ["tau_1"]
    first, second = table
    assert "hold=600 s" in str(first["what"]) and first["members"] == 2
    assert first["bias.tau_1"] == pytest.approx(0.02)
    assert first["sd.tau_1"] == pytest.approx(np.std([0.01, 0.03], ddof=1))
    assert first["cov.tau_1"] == 1.0 and second["cov.tau_1"] == 0.0


def test_lclg_separation_between_two_truths(tmp_path):
    rows = [_row(i, 2000, 0, 1e9, unloading=u, lclg={"2.38e-05": v, "0.000237": v + 0.05})
            for i, (u, v) in enumerate([("cutoff", 0.90), ("cutoff", 0.92),
                                        ("mdr", 0.80), ("mdr", 0.82)])]
    data = lclg_by_truth(rows)
    assert set(data) == {"unloading=cutoff", "unloading=mdr"}
    np.testing.assert_allclose(data["unloading=mdr"][2.38e-5], [0.80, 0.82])
    page = write_campaign_report(tmp_path, "t", rows)
    csv = (tmp_path / "lclg_by_speed.csv").read_text().splitlines()
    header = csv[0].split(",")
    sep = header.index("separation_sd")
    sd = np.std([0.90, 0.92], ddof=1)
    assert float(csv[1].split(",")[sep]) == pytest.approx(0.10 / sd)
    assert "lclg_vs_speed.png" in page.read_text()


def test_z_scores_measure_errors_in_reported_standard_errors():
    rows = [_row(i, 2000 + d, 2000 + d - 3.92 * 5, 2000 + d + 3.92 * 5)  # s.e. 10
            for i, d in enumerate((-20.0, 0.0, 20.0))]
    np.testing.assert_allclose(z_scores(rows, "tau_1"), [-2.0, 0.0, 2.0])


def test_a_report_where_every_interval_holds_or_none_does(tmp_path):
    rows = [_row(i, 2000, 1000, 3000, variant={"v": 1}) for i in range(7)]
    rows += [_row(10 + i, 2500, 2400, 2600, variant={"v": 2}) for i in range(7)]
    page = write_campaign_report(tmp_path, "t", rows)
    table, _ = variant_rows(rows)
    assert [r["cov.tau_1"] for r in table] == [1.0, 0.0]
    assert (tmp_path / "coverage.png").exists() and "coverage.png" in page.read_text()


def test_a_hold_fit_is_compared_by_its_ramp_corrected_amplitudes():
    """The truth holds the material's G_1; the hold fit's amplitude is the hold start's,
    smaller by the relaxation during the ramp: the member reports the corrected one, its
    standard error scaled alike (tau's as fitted)."""
    from types import SimpleNamespace

    from gelrig.campaign.member import Z95, fitted_columns
    from gelrig.instrument.analysis.relaxation import RelaxationFit, RelaxationTerm

    fit = RelaxationFit(7000.0, (RelaxationTerm(600.0, 1400.0),), 0.0, 1.0,
                        {"G_e": 2.0, "G_1": 6.0, "tau_1": 30.0}, 1000,
                        extra={"relax_ramp_corrected": [{"G": 630.0, "tau": 1400.0}]},
                        terms_resolved=1)
    result = SimpleNamespace(hold_fits={1: [fit]},
                             holds={1: SimpleNamespace(duration=600.0, overlap=None)},
                             model_fits={}, ladders={})
    out = fitted_columns(result)
    assert out["fit.G_1"] == 630.0 and out["se.G_1"] == pytest.approx(6.3)
    assert out["hi.G_1"] == pytest.approx(630.0 + Z95 * 6.3)
    assert (out["fit.tau_1"], out["se.tau_1"]) == (1400.0, 30.0)
    assert (out["fit.G_e"], out["se.G_e"]) == (7000.0, 2.0)
    assert "fit.first_touch" not in out  # no ramp refit: no first touch to compare


def test_members_whose_fit_is_not_resolved_are_left_out_and_counted():
    """A member whose hold fit the data do not resolve (``resolved`` false) is no result:
    coverage, bias and the z-scores leave it out, and the summary says how many."""
    from gelrig.campaign.report import summary_lines, unresolved

    rows = [_row(0, 2000, 1900, 2100), _row(1, 2050, 2010, 2090),
            {**_row(2, 9000, 100, 200), "resolved": False, "not_resolved": "BIC"}]
    c = coverage(rows, "tau_1")
    assert (c.hits, c.n, c.unresolved) == (1, 2, 1)
    assert unresolved(rows, "tau_1") == 1
    assert relative_errors(rows, "tau_1").size == 2 and z_scores(rows, "tau_1").size == 2
    lines = summary_lines(rows)
    assert "1 ok but not resolved" in lines[0]
    assert "1 member(s) not resolved, left out" in lines[1]
    table, _ = variant_rows(rows)
    assert table[0]["not_resolved"] == 1
