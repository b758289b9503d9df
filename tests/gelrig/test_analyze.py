"""``gelrig analyze`` on runs recorded from the simulated rigs, complete and broken.

The shear run: a shortened ladder (2 overlaps x 3 speeds, C and AC) on the built-in
simulated MCR 501 (hidden truth of protocols/rigs/shear.toml: G_e 4 kPa, 20 kPa / 2000 s,
mu 5e-3, touch gap 3 mm, lower sphere at 0.8 rad), given a touch gap 12 um and a centre
angle 0.7 mrad off, as the contact search reports them. The compression run: a ramp to 6 %
and a 600 s hold at 100 Hz (truth: G_e 7146 Pa, 630 Pa / 1413 s).
"""

import json
import math
import shutil

import h5py
import numpy as np
import pytest

from gelrig.analyze_run import analyze_run
from gelrig.cli import main
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import record_run

SHEAR_STEPS = [{"kind": "speed_ladder", "name": "ladder", "overlaps": 2,
                "first_overlap": "0.45 mm", "overlap_step": "0.25 mm",
                "speeds": ["2.38e-5 m/s", "1.19e-4 m/s", "2.37e-4 m/s"], "travel": "14 mm",
                "wait": "30 s", "touch_gap": "3.012 mm", "centre_angle": 0.7993}]
HOLD_STEPS = [{"kind": "compression_contact_search", "name": "contact search", "probe": "0.5 mm",
               "speed": "0.3 mm/s", "threshold": "5 mN", "retract": "0.5 mm", "confirm": 2,
               "rate": "100 Hz"},
              {"kind": "ramp_hold", "diameter": "18.63 mm", "name": "ramp and hold",
               "hold": "600 s", "rate": "100 Hz",
               "terms": 1}]


def record(kind, steps, path):
    protocol = parse_protocol({"protocol": {"name": f"short {kind}", "rig": kind},
                               "step": steps})
    spec = load_rig(default_rig(kind))
    run = RunDirectory.create(path, {"protocol": protocol.table, "rig": spec.table})
    state, _ = record_run(protocol, spec, VirtualClock(), run, show=False)
    assert state is RunState.COMPLETED
    return run


@pytest.fixture(scope="module")
def shear_run(tmp_path_factory):
    return record("shear", SHEAR_STEPS, tmp_path_factory.mktemp("shear") / "run")


@pytest.fixture(scope="module")
def hold_run(tmp_path_factory):
    return record("compression", HOLD_STEPS, tmp_path_factory.mktemp("hold") / "run")


@pytest.fixture(scope="module")
def shear_report(shear_run, tmp_path_factory):
    return analyze_run(shear_run.path, tmp_path_factory.mktemp("report"))


def test_shear_report_recovers_the_hidden_truth(shear_report):
    result = shear_report
    assert result.complete, result.problems
    fit = result.model_fits[0]
    # tolerances of docs/decisions/0030 for simulated runs
    assert fit.material.g_e == pytest.approx(4e3, rel=0.03)
    assert fit.material.relax[0].g == pytest.approx(2e4, rel=0.03)
    assert fit.material.relax[0].tau == pytest.approx(2000.0, rel=0.05)
    assert fit.mu == pytest.approx(5e-3, rel=0.03)
    assert fit.touch_gap == pytest.approx(3e-3, abs=2e-6)
    assert fit.lower_angle == pytest.approx(0.8, abs=1e-4)
    levels = result.ladders[0].levels()
    assert len(levels) == 6
    for row in levels:
        assert row["l_c_C_m"] < row["l_g_m"] and row["l_c_AC_m"] < row["l_g_m"]
        assert row["mu"] == pytest.approx(5e-3, rel=0.2)  # the bound; seen: < 2 %
    for overlap in {row["overlap_m"] for row in levels}:
        ratios = [r["l_c_over_l_g"] for r in sorted(levels, key=lambda r: r["speed_m_s"])
                  if r["overlap_m"] == overlap]
        assert all(np.diff(ratios) > 0), ratios


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_report_has_figures_tables_and_csv(shear_report):
    page = shear_report.report_path
    text = page.read_text()
    images = [part.split('"')[0] for part in text.split('<img src="')[1:]]
    assert len(images) >= 7
    for name in images:
        assert (page.parent / name).stat().st_size > 5000
    for csv_name in ("ladder_00_levels.csv", "ladder_00_passes.csv", "ladder_00_model_fit.csv"):
        assert f'href="{csv_name}"' in text
        lines = (page.parent / csv_name).read_text().splitlines()
        assert len(lines) > 1
    header = (page.parent / "ladder_00_passes.csv").read_text().splitlines()[0].split(",")
    assert {"l_c_m", "l_g_m", "f_h_peak_N", "f_h_trough_N", "zero_offset_m", "mu"} <= set(header)
    assert "<script" not in text
    summary = shear_report.summary
    assert len(summary.splitlines()) <= 40 and "l_c/l_g" in summary and "G_e" in summary


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_cli_prints_the_summary(shear_run, tmp_path, capsys):
    assert main(["analyze", str(shear_run.path), "--out", str(tmp_path / "r"),
                 "--no-model-fit"]) == 0
    out = capsys.readouterr().out
    assert "l_c/l_g" in out and (tmp_path / "r" / "report.html").exists()
    assert "model fit" not in out


def test_hold_report(hold_run, tmp_path):
    result = analyze_run(hold_run.path, tmp_path)
    assert result.complete, result.problems
    one, two = result.hold_fits[1]
    assert one.g_e == pytest.approx(7146.0, rel=0.02)
    assert one.relax[0].tau == pytest.approx(1413.0, rel=0.2)
    assert len(two.relax) == 2 and math.isfinite(two.rmse)
    text = result.report_path.read_text()
    assert "hold_01.png" in text and (tmp_path / "hold_01_residuals.csv").exists()
    assert "1-term" in result.summary and "2-term" in result.summary


def _copy(run, tmp_path, name="copy"):
    target = tmp_path / name
    shutil.copytree(run.path, target)
    return RunDirectory(target)


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_missing_step_file_is_named(shear_run, tmp_path, capsys):
    copy = _copy(shear_run, tmp_path)
    (copy.path / "steps" / "00_ladder.h5").unlink()
    with pytest.raises(ConfigError, match=r"00_ladder\.h5 is missing"):
        analyze_run(copy.path, tmp_path / "out")
    assert main(["analyze", str(copy.path)]) == 2
    assert "00_ladder.h5 is missing" in capsys.readouterr().err


def test_crash_mid_ladder_analyses_the_complete_passes(shear_run, tmp_path):
    """A run killed during pass 7: status 'running', data ends mid-pass."""
    copy = _copy(shear_run, tmp_path)
    path = copy.path / "steps" / "00_ladder.h5"
    with h5py.File(path, "r") as handle:
        label = handle["pass"][:]
    cut = int(np.flatnonzero(label == 7)[len(np.flatnonzero(label == 7)) // 2])
    with h5py.File(path, "r+") as handle:
        for name in list(handle):
            handle[name].resize((cut,))
    meta = copy.read_metadata()
    meta["status"] = "running"
    meta["steps"][0].update(status="running", results=None)
    copy.write_metadata(meta)
    result = analyze_run(copy.path, tmp_path / "out")
    text = "\n".join(result.problems)
    assert "step 0 (ladder) is running, not completed" in text
    assert "pass 7 is truncated" in text
    assert "no opposite pass" in text and "6" in text
    analysed = sorted(r.index for r in result.ladders[0].results)
    assert analysed == [0, 1, 2, 3, 4, 5, 6]
    # 7 fresh passes tell G_e from G_1 only by the decay within each contact (ADR 0140)
    assert result.model_fits[0].material.g_e == pytest.approx(4e3, rel=0.1)
    assert "INCOMPLETE" in result.summary
    assert "Incomplete data" in result.report_path.read_text()


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_step_never_started_is_reported(hold_run, tmp_path):
    copy = _copy(hold_run, tmp_path)
    meta = copy.read_metadata()
    extra = dict(meta["protocol"]["step"][1], name="second hold")
    meta["protocol"]["step"].append(extra)
    meta["status"] = "aborted"
    copy.write_metadata(meta)
    result = analyze_run(copy.path, tmp_path / "out")
    assert any("step 2 (second hold, ramp_hold) was never recorded" in p
               for p in result.problems)
    assert 1 in result.hold_fits


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_truncated_hold_is_fitted_and_flagged(hold_run, tmp_path):
    copy = _copy(hold_run, tmp_path)
    path = copy.path / "steps" / "01_ramp_and_hold.h5"
    with h5py.File(path, "r") as handle:
        n = handle["t_s"].shape[0]
    with h5py.File(path, "r+") as handle:
        for name in list(handle):
            handle[name].resize((n // 2,))
    result = analyze_run(copy.path, tmp_path / "out")
    assert any("hold recorded for" in p and "planned 600 s" in p for p in result.problems)
    assert result.hold_fits[1][0].g_e == pytest.approx(7146.0, rel=0.1)


def test_not_a_run_directory(tmp_path):
    with pytest.raises(ConfigError, match=r"no run\.json"):
        analyze_run(tmp_path, tmp_path / "out")
    (tmp_path / "run.json").write_text(json.dumps({"steps": []}))
    with pytest.raises(ConfigError, match="no recorded data"):
        analyze_run(tmp_path, tmp_path / "out")


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_the_ladder_shows_the_chord_per_pass_and_per_speed(shear_report):
    """Issue 14 item 4: the measured l_g beside the chord 2 psi0 at the set overlap (the
    ladder's touch gap), per (overlap, speed) and per pass, in the summary and the report."""
    s = 9.2e-3 + 9.96e-3  # R1 + R2 of analyze_run's defaults (the paper's)
    text = shear_report.report_path.read_text()
    levels = (shear_report.out_dir / "ladder_00_levels.csv").read_text().splitlines()
    header = levels[0].split(",")
    assert {"l_g_m", "l_g_chord_m", "l_g_over_chord", "l_c_over_l_g"} <= set(header)
    for line in levels[1:]:
        row = dict(zip(header, line.split(","), strict=True))
        overlap = float(row["overlap_m"])
        expect = 2 * math.sqrt(s**2 - (s - overlap) ** 2)
        assert float(row["l_g_chord_m"]) == pytest.approx(expect, rel=1e-9)
        assert float(row["l_g_over_chord"]) == pytest.approx(
            float(row["l_g_m"]) / expect, rel=1e-9)
    passes = (shear_report.out_dir / "ladder_00_passes.csv").read_text().splitlines()[0]
    assert "l_g_chord_m" in passes.split(",")
    assert "chord at the set overlap" in text
    summary = shear_report.summary
    for overlap in (0.45e-3, 0.70e-3):
        chord = 2 * math.sqrt(s**2 - (s - overlap) ** 2)
        assert f"{overlap * 1e3:.2f} mm  chord {chord * 1e3:6.3f} mm  l_g (mm)" in summary
    assert summary.count("l_c/l_g") >= 2


def test_a_step_recorded_after_a_clock_restart_is_joined_in_time_order():
    """A run resumed before resumes continued the time base: the ladder's times start at 0
    again, after a contact search that ended at 700 s; the model fit needs the motion in time
    order, so the ladder is moved on, and the problems say so."""
    from gelrig.analyze_run import StepData, _history

    def columns(t0: float) -> dict:
        t = t0 + np.arange(5.0)
        return {"t_s": t, "angle_rad": t * 0, "gap_m": t * 0 + 3e-3, "torque_Nm": t * 0,
                "normal_force_N": t * 0, "pass": t * 0, "direction": t * 0 + 1}

    search = StepData(0, "shear_contact_search", "contact search", "completed", {}, {},
                      columns(700.0))
    ladder = StepData(1, "speed_ladder", "ladder", "completed", {}, {}, columns(0.1))
    problems: list[str] = []
    history = _history([search, ladder], ladder, problems)
    t = np.concatenate([h["t_s"] for h in history])
    assert (np.diff(t) > 0).all()
    assert len(problems) == 1 and "restarted the clock" in problems[0]
    in_order: list[str] = []
    joined = _history([search, StepData(1, "speed_ladder", "ladder", "completed", {}, {},
                                        columns(800.0))], ladder, in_order)
    assert in_order == [] and joined[1]["t_s"][0] == 800.0  # a continuous run: as recorded
