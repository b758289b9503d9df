"""``gelrig analyze --unloading`` and ``--anisotropic`` on ladders that went through the whole
simulated rig (simulator, wire, driver, runner, recorder), reduced as in
test_paper_shear_features: the deepest overlap at the two fastest speeds.

- A ladder simulated with MDR unloading, fitted with MDR, recovers the simulator's truth; the
  cutoff model fitted to the same data is measurably worse (its residual is several times the
  noise, MDR's is the noise).
- A ladder simulated with the paper's anisotropy (F_v with its own G_l), fitted with
  ``--anisotropic``, recovers both amplitudes and reports both with intervals in the summary,
  the report and the CSV.
"""

from __future__ import annotations

import csv

import pytest

from gelrig.analyze_run import AnalysisResult, analyze_run
from gelrig.cli import main
from gelrig.instrument.analysis.model_fit import ModelFit
from gelrig.instrument.core.store import RunDirectory
from tests.gelrig import paper_ladder
from tests.gelrig.test_paper_shear_features import REDUCED_SPEEDS


def reduced(tmp_path_factory: pytest.TempPathFactory, name: str, **simulator: object
            ) -> RunDirectory:
    spec = paper_ladder.rig(**simulator)
    return paper_ladder.record(tmp_path_factory.mktemp(name) / "run", spec,
                               paper_ladder.protocol(overlaps=1, speeds=REDUCED_SPEEDS))


def only_fit(result: AnalysisResult) -> ModelFit:
    assert result.complete, result.problems
    (fit,) = result.model_fits.values()
    return fit


@pytest.fixture(scope="module")
def mdr_run(tmp_path_factory: pytest.TempPathFactory) -> RunDirectory:
    return reduced(tmp_path_factory, "mdr", unloading="mdr")


@pytest.fixture(scope="module")
def mdr_fits(mdr_run: RunDirectory, tmp_path_factory: pytest.TempPathFactory
             ) -> dict[str, AnalysisResult]:
    out = tmp_path_factory.mktemp("mdr_analysis")
    return {model: analyze_run(mdr_run.path, out / model, unloading=model)
            for model in ("mdr", "cutoff")}


def test_an_mdr_ladder_fitted_with_mdr_recovers_the_truth(mdr_fits):
    truth = paper_ladder.rig(unloading="mdr").simulator
    fit = only_fit(mdr_fits["mdr"])
    assert fit.extra["unloading"] == "mdr"
    expected = {"G_e": truth.material.g_e, "G_1": truth.material.relax[0].g,
                "tau_1": truth.material.relax[0].tau, "mu": truth.mu}
    for name, value in expected.items():
        e = fit.estimate(name)
        assert e.lo <= value <= e.hi or e.value == pytest.approx(value, rel=0.03), (name, e)
    # at the noise floor: nothing left for the model to explain
    assert fit.rms_h < 1.5 * fit.noise_h and fit.rms_v < 1.5 * fit.noise_v


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_the_cutoff_model_fits_an_mdr_ladder_measurably_worse(mdr_fits):
    mdr, cutoff = only_fit(mdr_fits["mdr"]), only_fit(mdr_fits["cutoff"])
    assert cutoff.extra["unloading"] == "cutoff"
    assert cutoff.rms_h > 2.0 * mdr.rms_h and cutoff.rms_h > 2.0 * cutoff.noise_h
    assert cutoff.rms_v > 2.0 * mdr.rms_v


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_the_summary_and_the_report_name_the_unloading_model(mdr_fits):
    for model, result in mdr_fits.items():
        assert f"{model} unloading" in result.summary
        assert f"{model} unloading" in result.report_path.read_text()


@pytest.fixture(scope="module")
def anisotropic(tmp_path_factory: pytest.TempPathFactory) -> tuple[AnalysisResult, object]:
    spec = paper_ladder.rig(relax_vertical=[["16 kPa", "2000 s"]])
    run = reduced(tmp_path_factory, "aniso", relax_vertical=[["16 kPa", "2000 s"]])
    result = analyze_run(run.path, tmp_path_factory.mktemp("aniso_analysis"), anisotropic=True)
    return result, spec.simulator


def test_an_anisotropic_fit_recovers_both_amplitudes_with_intervals(anisotropic):
    result, truth = anisotropic
    fit = only_fit(result)
    g_h, g_v = fit.estimate("G_1_h"), fit.estimate("G_1_v")
    for e, value in ((g_h, truth.material.relax[0].g),
                     (g_v, truth.material_vertical.relax[0].g)):
        assert e.lo < e.value < e.hi
        assert e.lo <= value <= e.hi or e.value == pytest.approx(value, rel=0.05), e
    assert g_v.hi < g_h.lo  # told apart
    assert "G_1_h" in result.summary and "G_1_v" in result.summary
    assert "separately for F_h" in result.summary
    page = result.report_path.read_text()
    assert "G_1_h" in page and "G_1_v" in page
    (table,) = result.out_dir.glob("*_model_fit.csv")
    with table.open() as f:
        rows = {r["parameter"]: r for r in csv.DictReader(f)}
    for name in ("G_1_h", "G_1_v"):
        assert float(rows[name]["ci95_lo"]) < float(rows[name]["value"]) < float(
            rows[name]["ci95_hi"])


@pytest.mark.parametrize("args, words", [
    (["--unloading", "hertz"], "--unloading: invalid choice: 'hertz'"),
    (["--anisotropic=yes"], "--anisotropic: ignored explicit argument 'yes'"),
])
def test_bad_options_are_one_line_and_exit_2(args, words, capsys, tmp_path):
    assert main(["analyze", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and "Traceback" not in err


def test_the_options_reach_the_fit_from_the_command_line(mdr_run, capsys, tmp_path):
    assert main(["analyze", str(mdr_run.path), "--out", str(tmp_path / "a"),
                 "--unloading", "mdr", "--anisotropic"]) == 0
    out = capsys.readouterr().out
    assert "mdr unloading" in out and "G_1_h" in out and "G_1_v" in out
