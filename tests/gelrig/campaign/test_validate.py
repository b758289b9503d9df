"""``gelrig validate``: the suite's files, the claims measured on rows, the one report, and
one-line errors for bad options."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gelrig.campaign.validate import CLAIMS, coverage_band, load_suite, suite_dir
from gelrig.cli import main

Z95 = 1.959963984540054


def _rows(n: int, inside: int, error: float = 0.0, extra: dict | None = None) -> list[dict]:
    """n ok members of one variant; the first ``inside`` hold G_e's truth in their interval;
    the fitted value off the truth by ``error`` (relative) plus a seeded scatter."""
    import numpy as np

    rng = np.random.default_rng(5)
    rows = []
    for i in range(n):
        fit = 1000.0 * (1 + error + 0.001 * rng.standard_normal())
        se = 3.0 if i < inside else 1e-9
        lo, hi = (fit - Z95 * se, fit + Z95 * se)
        if i < inside:
            lo, hi = min(lo, 999.0), max(hi, 1001.0)
        rows.append({"member_id": str(i), "index": i, "seed": i, "status": "ok",
                     "variant": "{}", "truth_variant": "{}", "terms_resolved": 1,
                     "truth.G_e": 1000.0, "fit.G_e": fit, "se.G_e": se, "lo.G_e": lo,
                     "hi.G_e": hi, "truth.tau_1": 1.0, **(extra or {})})
    return rows


def test_coverage_claim_passes_in_the_band_and_fails_below_it() -> None:
    claim = CLAIMS["hold.coverage"]
    assert coverage_band(20) == 17
    assert claim.evaluate(_rows(20, 18)).status == "pass"
    low = claim.evaluate(_rows(20, 15))
    assert low.status == "fail"
    assert low.rows[0]["hits"] == 15 and low.rows[0]["at_least"] == 17


def test_coverage_counts_resolved_members_only() -> None:
    rows = _rows(20, 20)
    for r in rows[:5]:
        r["terms_resolved"] = 0
    verdict = CLAIMS["hold.coverage"].evaluate(rows)
    assert verdict.rows[0]["n"] == 15
    assert "5 member(s) not resolved" in verdict.measured


def test_bias_claim_finds_a_bias_outside_the_spread() -> None:
    assert CLAIMS["hold.bias"].evaluate(_rows(20, 20)).status == "pass"
    assert CLAIMS["hold.bias"].evaluate(_rows(20, 20, error=0.01)).status == "fail"


def test_per_pass_claims_wait_for_their_columns() -> None:
    claim = CLAIMS["shear.l_g"]
    assert claim.evaluate(_rows(5, 5)).status == "not measured"
    assert claim.evaluate(_rows(5, 5, extra={"pass.lg_chord_rel_max": 0.001})).status == "pass"
    assert claim.evaluate(_rows(5, 5, extra={"pass.lg_chord_rel_max": 0.004})).status == "fail"
    # a pass without the figure (NaN recorded) is not within the bound
    nan = claim.evaluate(_rows(5, 5, extra={"pass.lg_chord_rel_max": float("nan")}))
    assert nan.status == "fail" and nan.measured.startswith("0/5 members")


def test_ladder_members_count_as_resolved() -> None:
    """A ladder fit records no terms_resolved: its members are in the coverage."""
    rows = _rows(20, 20)
    for r in rows:
        del r["terms_resolved"]
    verdict = CLAIMS["ladder.coverage"].evaluate(rows)
    assert verdict.status == "pass" and verdict.rows[0]["n"] == 20


def test_the_built_in_suite_loads_with_the_readme_grid() -> None:
    full = {c.name: c for c in load_suite(suite_dir(), quick=False)}
    assert {"hold_plate", "hold_shell", "paper_ladder"} <= set(full)
    plate = full["hold_plate"].spec
    assert len(plate.truth_grid["noise"]) == 4 and plate.replicates >= 20
    assert {len(v) for v in plate.param_grid.values()} == {1, 2}
    assert all(c.spec.replicates >= 20 for c in full.values())
    quick = load_suite(suite_dir(), quick=True)
    assert [c.name for c in quick] == ["hold_plate", "paper_ladder"]
    assert all(len(c.spec.members) == c.spec.replicates for c in quick)


@pytest.mark.parametrize("argv, text", [
    (["--workers", "0"], "allowed: a whole number 1..1024"),
    (["--only", "nosuch"], "allowed: hold_plate"),
    (["--only", ","], "campaign names"),
    (["--suite", "EMPTY"], "no validate_*.toml"),
])
def test_bad_options_are_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture,
                                             argv: list[str], text: str) -> None:
    argv = [str(tmp_path) if a == "EMPTY" else a for a in argv]
    assert main(["validate", "--out", str(tmp_path / "out"), *argv]) == 2
    err = capsys.readouterr().err
    assert text in err and err.count("\n") == 1


def test_a_suite_file_without_its_claims_is_refused(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    (tmp_path / "validate_x.toml").write_text(
        '[campaign]\nprotocol = "paper:compression"\n[validate]\nclaims = ["nope"]\n')
    assert main(["validate", "--suite", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "[validate] claims" in capsys.readouterr().err


@pytest.mark.slow
def test_quick_suite_writes_one_report_of_its_claims(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "v"
    code = main(["validate", "--quick", "--workers", "1", "--no-progress", "--out", str(out)])
    printed = capsys.readouterr().out
    report = json.loads((out / "validate.json").read_text())
    claims = {c["claim"]: c for c in report["claims"]}
    assert set(claims) == {"hold.coverage", "hold.bias", "first_touch", "ladder.coverage",
                           "ladder.bias", "shear.l_g", "shear.l_c", "shear.lc_lg", "shear.mu"}
    assert report["commands"] == ["gelrig validate --quick"]
    assert (out / "validate.html").is_file() and (out / "validate_coverage.png").is_file()
    assert {c["campaign"]: c["members"] for c in claims.values()} == {"hold_plate": 6,
                                                                      "paper_ladder": 2}
    # the shear members record their passes: the per-pass claims are measured (issue 26)
    shear = [c for k, c in claims.items() if k.startswith("shear.")]
    assert all(c["verdict"]["status"] in ("pass", "fail") for c in shear)
    assert all(c["verdict"]["measured"].endswith(tuple("0123456789")) for c in shear)
    assert code == (1 if any(c["verdict"]["status"] == "fail" for c in claims.values()) else 0)
    assert "hold.coverage" in printed and "report:" in printed
