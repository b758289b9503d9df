"""``gelrig analyze`` on runs of any steps, and ``gelrig series``, through the whole simulated
compression rig in virtual time (simulators, wire, drivers, runner, recorder, analysis).

The rig is the built-in one with a faster material, so that holds of 90-150 s resolve it:
G_e 7146 Pa, 2000 Pa / 60 s (retardation time tau_c = tau G_0 / G_e = 76.8 s); noise 0.2 mN.
Every fitted value is compared with that truth through its own 95 % interval.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import pytest

import gelrig
from gelrig.analyze_run import analyze_run
from gelrig.cli import main
from gelrig.protocols.rigfile import default_rig
from tests.gelrig import dwell_steps  # noqa: F401 (registers the user kind "dwells")

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
G_E, G_1, TAU = 7146.0, 2000.0, 60.0
TAU_C = TAU * (G_E + G_1) / G_E
SPHERE = {"name": "the simulated rig's sphere", "diameter": 18.63e-3}


def within(row_or_fit: dict, name: str, truth: float) -> None:
    lo, hi = row_or_fit[f"{name}_lo"], row_or_fit[f"{name}_hi"]
    assert lo <= truth <= hi, (name, row_or_fit[name], lo, hi, truth)


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rig") / "fast.toml"
    path.write_text(re.sub(r'(?m)^relax = .*$', f'relax = [["{G_1:g} Pa", "{TAU:g} s"]]',
                           default_rig("compression").read_text()))
    return path


@gelrig.protocol(rig="compression", name="creep, stops, rest, cycle")
def mixed(run: gelrig.Run) -> None:
    """User kinds only after the contact search: a creep, two stops inside one step, a rest,
    a loading-unloading cycle."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    run.step("creep", name="creep", force="60 mN", hold="150 s", speed="37 um/s",
             period="1 s", gain=0.5, rate="100 Hz")
    run.step("dwells", name="two stops", first="0.4 mm", second="0.8 mm", dwell="90 s")
    run.step("rest", name="rest", duration="20 s", clear="2 mm")
    run.step("load_unload", name="cycle", strain=0.02, speed="50 um/s", approach="0.05 mm")


@gelrig.protocol(rig="compression", name="nothing to fit")
def unanalysable(run: gelrig.Run) -> None:
    """A rest and a cycle: no hold anywhere."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    run.step("rest", name="rest", duration="10 s", clear="2 mm")
    run.step("load_unload", name="cycle", strain=0.02, speed="50 um/s", approach="0.05 mm")


def record(rig: Path, protocol: object, out: Path) -> Path:
    with gelrig.open_rig(rig) as session:
        result = session.run(protocol, out=out, sample=SPHERE)  # type: ignore[arg-type]
    assert result.ok, result.reason
    return Path(result.path)


@pytest.fixture(scope="module")
def mixed_run(rig: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return record(rig, mixed, tmp_path_factory.mktemp("mixed") / "run")


@pytest.fixture(scope="module")
def mixed_analysis(mixed_run: Path):
    return analyze_run(mixed_run)


@pytest.fixture(scope="module")
def series_run(rig: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    script = gelrig.load_protocol(EXAMPLES / "relaxation_series.py")
    assert isinstance(script, gelrig.Script)
    return record(rig, script.with_params(strains=(0.02, 0.04), hold="90 s", rest="20 s"),
                  tmp_path_factory.mktemp("series") / "run")


# -- any run: columns drawn, holds found ----------------------------------------------------
def test_every_step_gets_its_columns_drawn(mixed_analysis) -> None:
    result = mixed_analysis
    assert result.complete, result.problems
    page = result.report_path.read_text()
    for index in range(5):
        png = result.out_dir / f"step_{index:02d}_columns.png"
        assert png.is_file() and png.name in page, png
        assert (result.out_dir / f"step_{index:02d}_force_position.png").is_file()
    assert "recorded columns" in page


def test_a_creep_hold_is_found_and_fitted(mixed_analysis) -> None:
    (hold,) = mixed_analysis.found[1]
    assert hold.kind == "creep" and not hold.not_resolved
    assert hold.segment.duration == pytest.approx(150.0, abs=2.0)
    fit = hold.creep
    assert fit is not None and fit.is_resolved and not fit.partial
    row = {}
    for name in ("G_e", "G_1", "tau_1", "tau_c"):
        value, err = fit.values[name], fit.stderr[name]
        row |= {name: value, f"{name}_lo": value - 1.96 * err, f"{name}_hi": value + 1.96 * err}
    for name, truth in (("G_e", G_E), ("tau_1", TAU), ("tau_c", TAU_C)):
        within(row, name, truth)
    assert fit.values["G_1"] == pytest.approx(G_1, rel=0.01)  # its interval: 0.2 %, seen 0.25 %
    assert (mixed_analysis.out_dir / "step_01_creep_1.png").is_file()
    assert "hold 1: creep" in mixed_analysis.summary


def test_holds_inside_a_custom_step_are_found_and_fitted(mixed_analysis) -> None:
    holds = mixed_analysis.found[2]
    assert [h.kind for h in holds] == ["relaxation", "relaxation"]
    for hold, depth in zip(holds, (0.4e-3, 0.8e-3), strict=True):
        assert hold.overlap == pytest.approx(depth, abs=5e-6)
        assert hold.segment.duration == pytest.approx(90.0, abs=2.0)
        fit = hold.relaxation.fits[-1].resolved
        assert fit.is_resolved and len(fit.relax) == 1
        tau, err = fit.relax[0].tau, fit.stderr["tau_1"]
        assert abs(tau - TAU) < 1.96 * err, (tau, err)
        assert abs(fit.g_e - G_E) < 1.96 * fit.stderr["G_e"], (fit.g_e, fit.stderr)
    # the second stop keeps the first's first touch (refitted on the ramp)
    assert holds[0].first_touch is not None
    assert holds[1].relaxation.overlap is None


def test_no_hold_where_there_is_none(mixed_analysis) -> None:
    assert mixed_analysis.found[0] == mixed_analysis.found[3] == mixed_analysis.found[4] == []


def test_a_run_with_nothing_to_fit_still_gets_its_plots(rig: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    run = record(rig, unanalysable, tmp_path / "run")
    assert main(["analyze", str(run), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "0 hold(s) found" in out and "report:" in out
    for index in range(3):
        assert (tmp_path / "out" / f"step_{index:02d}_columns.png").is_file()


def test_a_run_without_recorded_data_is_one_line(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "run.json").write_text('{"steps": []}')
    assert main(["analyze", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no recorded data" in err


# -- series ----------------------------------------------------------------------------------
def test_series_compares_every_hold_with_intervals(series_run: Path, mixed_run: Path,
                                                   tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "series"
    assert main(["series", str(series_run), str(mixed_run), "--out", str(out)]) == 0
    assert "report:" in capsys.readouterr().out
    with (out / "series.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    kinds = [(r["run"], r["hold"]) for r in rows]
    assert kinds == [("run", "relaxation")] * 2 + [("run", "creep")] + [("run", "relaxation")] * 2
    strains = [float(r["strain"]) for r in rows[:2]]
    assert strains == pytest.approx([0.02, 0.04], abs=5e-4)
    for r in rows:
        assert r["resolved"] == "true", r
        num = {k: float(v) for k, v in r.items() if re.fullmatch(r"(G_e|G_1|tau_1)(_lo|_hi)?", k)}
        within(num, "tau_1", TAU)
        within(num, "G_e", G_E)
        assert float(r["hold_s"]) > 80
    for r in rows[:2]:  # the ramp-corrected G_1 of a ramp_hold
        within({k: float(r[k]) for k in ("G_1", "G_1_lo", "G_1_hi")}, "G_1", G_1)
    assert (out / "series.png").is_file() and (out / "report.html").is_file()


def test_series_names_a_folder_that_is_not_a_run(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["series", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(tmp_path) in err and "not a run" in err
    assert not (tmp_path / "out").exists()


def test_the_hold_rows_carry_no_values_when_not_resolved(mixed_analysis) -> None:
    from gelrig.instrument.analysis.found_holds import hold_row

    hold = mixed_analysis.found[1][0]
    assert hold.creep is not None
    unresolved = type(hold)(hold.segment, hold.overlap, hold.force,
                            creep=type(hold.creep)(**{**hold.creep.__dict__,
                                                      "not_resolved": "test"}),
                            not_resolved="test")
    row = hold_row(unresolved, 18.63e-3)
    assert row["resolved"] is False and row["not_resolved"] == "test"
    assert all(row[k] is None for k in ("G_e", "G_1", "tau_1", "tau_c"))
    assert not any(math.isnan(v) for v in (hold.overlap, hold.force))
