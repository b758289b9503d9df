"""gelrig plan / run / resume / export on the built-in simulated rigs, and their bad inputs."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from gelrig.cli import main
from gelrig.instrument.core.store import RunDirectory, read_step
from tests.samples import SHORT_COMPRESSION

SHORT = SHORT_COMPRESSION


@pytest.fixture
def short(tmp_path):
    def make(hold="60 s"):
        path = tmp_path / f"short-{hold.replace(' ', '')}.toml"
        path.write_text(SHORT.format(hold=hold))
        return path
    return make


def one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("name", ["paper:compression", "paper:shear"])
def test_plan_prints_steps_duration_and_checks(capsys, name):
    assert main(["plan", name]) == 0
    out = capsys.readouterr().out
    assert "Total: ~" in out and "limit checks all passed" in out and "lab time" in out
    assert "rehearsal passed" in out  # then rehearsed on the twin (tests/gelrig/test_cli_plan)


def test_plan_fails_on_a_limit(tmp_path, capsys):
    path = tmp_path / "deep.toml"
    path.write_text('[protocol]\nname = "deep"\nrig = "shear"\n[[step]]\nkind = "speed_ladder"\n'
                    'first_overlap = "1.1 mm"\n')
    assert main(["plan", str(path)]) == 2
    captured = capsys.readouterr()
    assert "FAIL overlap" in captured.out
    assert "limit check" in captured.err and len(captured.err.strip().splitlines()) == 1


def test_bad_protocol_file(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(SHORT.format(hold="-5 s"))
    assert main(["run", str(path), "--out", str(tmp_path / "r")]) == 2
    line = one_error_line(capsys)
    assert "bad.toml" in line and "[step[1]] hold" in line and "-5" in line
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("edit,field", [
    (("max_position = \"12 mm\"", "max_position = \"40 mm\""),
     "[stage] max_position = \"40 mm\": allowed [0, 25] mm"),
    (("transport = \"simulator\"\ncounts_per_mm", "transport = \"usb\"\ncounts_per_mm"),
     "[stage] transport = \"usb\": allowed: simulator, serial"),
    (("max_force = \"2 N\"", "max_force = \"-2 N\""),
     "[limits] max_force = \"-2 N\": allowed (0, 100] N"),
    (("gain = 1000", "gain = \"loud\""), "[force.chain] gain = \"loud\""),
    (("[limits]", "[limitz]"), "[limitz]"),
])
def test_bad_rig_file(tmp_path, capsys, short, edit, field):
    from gelrig.protocols.rigfile import default_rig

    text = default_rig("compression").read_text()
    assert edit[0] in text
    rig = tmp_path / "rig.toml"
    rig.write_text(text.replace(edit[0], edit[1], 1))
    assert main(["run", str(short()), "--rig", str(rig), "--out", str(tmp_path / "r")]) == 2
    line = one_error_line(capsys)
    assert "rig.toml" in line and field in line


def test_clock_checks(tmp_path, capsys, short):
    from gelrig.protocols.rigfile import default_rig

    assert main(["run", str(short()), "--clock", "paced:0", "--out", str(tmp_path / "a")]) == 2
    assert "--clock" in one_error_line(capsys)
    hardware = default_rig("compression").read_text().replace(
        'transport = "simulator"\ncounts_per_mm',
        'transport = "serial"\naddress = "/dev/ttyUSB9"\ncounts_per_mm', 1)
    rig = tmp_path / "hw.toml"
    rig.write_text(hardware)
    assert main(["run", str(short()), "--rig", str(rig), "--clock", "virtual",
                 "--out", str(tmp_path / "b")]) == 2
    assert "virtual and paced time need a simulated rig" in one_error_line(capsys)


def test_run_then_export(tmp_path, capsys, short):
    out = tmp_path / "run"
    assert main(["run", str(short()), "--out", str(out)]) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "completed"
    assert meta["software"]["name"] == "gelrig" and meta["clock"] == "virtual"
    assert meta["instruments"]["stage"]["model"] == "KDC101"
    assert str(meta["instruments"]["stage"]["serial_number"]).startswith("27")
    assert meta["instruments"]["force"]["instrument"] == "NI USB-6001"
    assert meta["protocol"]["protocol"]["name"] == "short compression"
    assert meta["rig"]["rig"]["kind"] == "compression"
    # a 60 s hold resolves no term: run.json says so and the end-of-run line shows no values
    fits = meta["steps"][1]["results"]["fits"]
    assert [f["resolved"] for f in fits] == [False] * len(fits)
    printed = capsys.readouterr().out
    assert "1-term fit: not resolved: first term not resolved" in printed
    assert f"G_e {fits[0]['G_e']:.0f}" not in printed
    assert main(["export", str(out), "--csv"]) == 0
    hold = pd.read_csv(out / "csv" / "01_ramp_and_hold.csv")
    assert list(hold.columns) == ["t_s", "position_m", "delta_m", "force_N", "over_range",
                                  "position_flag"]
    assert hold["position_flag"].sum() == 0  # every position from the commanded path
    assert {"stage", "force"} <= set(meta["time_base"])  # each instrument's time mapping
    assert len(hold) == meta["steps"][1]["samples"] > 6000


def _wait_for(predicate, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError("condition not met in time")


def test_sigkill_mid_hold_keeps_data_and_resume_completes(tmp_path, short):
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "gelrig.cli", "run", str(short("300 s")), "--out", str(out),
         "--clock", "paced:20"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    run = RunDirectory(out)

    def holding():
        try:
            steps = run.read_metadata()["steps"]
        except Exception:
            return False
        if len(steps) < 2 or steps[1]["status"] != "running":
            return False
        try:
            data = run.read_step(1)
        except Exception:
            return False
        return data["t_s"].size > 0 and data["delta_m"].max() > 1.1e-3 and data

    try:
        seen = _wait_for(holding, 120)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
    flushed = seen["t_s"].size
    after_kill = run.read_step(1)  # readable after SIGKILL, and nothing flushed is lost
    assert after_kill["t_s"].size >= flushed
    assert run.read_metadata()["status"] == "running"

    assert main(["resume", str(out), "--clock", "virtual"]) == 0
    meta = run.read_metadata()
    assert meta["status"] == "completed"
    assert [s["status"] for s in meta["steps"]] == ["completed", "completed"]
    assert meta["steps"][1]["samples"] > 30000  # the hold ran again in full
    kept = meta["interrupted_steps"][0]
    assert kept["index"] == 1 and "attempt-1" in kept["file"]
    partial = pd.DataFrame(read_step(Path(out) / kept["file"]))
    assert len(partial) >= flushed
    # the attempt's extent comes from its file (the kill left run.json without it), and the
    # resumed hold starts after its last sample: one time base per run
    assert kept["samples"] == len(partial)
    assert kept["finished"] == partial["t_s"].iloc[-1]
    assert meta["steps"][1]["started"] >= kept["finished"]
    assert read_step(Path(out) / meta["steps"][1]["file"])["t_s"][0] > kept["finished"]


def test_demo_runs_both_paper_protocols(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    runs = summary["runs"]
    assert runs["compression"]["state"] == runs["shear"]["state"] == "completed"
    touch = runs["compression"]["results"]["0"]["first_touch_m"]
    assert touch == pytest.approx(6.2e-3, abs=10e-6)
    fit = runs["compression"]["results"]["1"]["fits"][0]
    assert fit["G_e"] == pytest.approx(7146, rel=0.02)
    assert fit["relax"][0]["tau"] == pytest.approx(1413, rel=0.02)
    assert runs["shear"]["results"]["0"]["touch_gap_m"] == pytest.approx(3e-3, abs=0.1e-3)
    assert len(runs["shear"]["results"]["1"]["passes"]) == 40
    for report in summary["reports"].values():
        assert Path(report).exists() and Path(report).suffix == ".html"
    out = capsys.readouterr().out
    assert str(tmp_path.resolve()) in out
    # the plates' second term is not resolved: its values are not printed as a result
    assert "plates 2-term fit: not resolved: second term not resolved" in out
    assert "fit stands" in out


def test_ctrl_c_pauses_then_aborts(tmp_path, short):
    # a step after the hold: wherever the Ctrl-C lands (a hold runs on: it cannot pause
    # without changing the physics), the run pauses at a checkpoint before the last step
    protocol = short("300 s")
    protocol.write_text(protocol.read_text() + '\n[[step]]\nkind = "compression_contact_search"'
                        '\nconfirm = 0\n')
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "gelrig.cli", "run", str(protocol), "--out", str(out),
         "--clock", "paced:20"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        stdin=subprocess.DEVNULL)
    run = RunDirectory(out)

    def status():
        try:
            return run.read_metadata().get("status")
        except Exception:
            return None

    try:
        _wait_for(lambda: status() == "running", 60)
        proc.send_signal(signal.SIGINT)
        _wait_for(lambda: status() == "paused", 60)  # at the next checkpoint
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3
    assert "Traceback" not in err and "pause requested" in err
    meta = run.read_metadata()
    assert meta["status"] == "aborted" and meta["reason"] == "aborted by Ctrl-C"


def test_end_of_run_lines_print_each_fit_once_and_no_unresolved_values():
    """run.json's fits of a hold: the 1-term fit once with its standard errors, the 2-term
    request as not resolved with the reason; a 60 s hold's lone fit prints no values."""
    from gelrig.commands.run import fit_lines

    one = {"G_e": 7146.0, "relax": [{"G": 630.0, "tau": 1413.0}], "terms_resolved": 1,
           "resolved": True, "stderr": {"G_e": 12.0, "G_1": 9.0, "tau_1": 40.0}}
    two = {**one, "terms_requested": 2,
           "not_resolved": "second term not resolved: BIC improvement 3 < 10",
           "unresolved_fit": {}}
    assert fit_lines([one, two]) == [
        "1-term fit: G_e 7146 +- 12 Pa, G_1 630 +- 9 Pa, tau_1 1413 +- 40 s",
        "2-term fit: not resolved: second term not resolved: BIC improvement 3 < 10"]
    short_hold = {"G_e": 7772.0, "relax": [{"G": 54.0, "tau": 104.0}], "terms_resolved": 0,
                  "resolved": False, "stderr": {"G_e": None},
                  "not_resolved": "first term not resolved: BIC improvement 2 < 10"}
    (line,) = fit_lines([short_hold])
    assert line == "1-term fit: not resolved: first term not resolved: BIC improvement 2 < 10"
    assert "7772" not in line and "104" not in line
    assert fit_lines([{"error": "too few samples"}]) == ["1-term fit failed: too few samples"]



def test_a_holds_g_1_is_shown_as_the_materials_with_the_hold_start_amplitude_beside():
    """A hold's fitted G_1 is the amplitude left at its start (625 Pa on the paper's ramp);
    the material's, corrected for relaxation during the ramp, is what a scientist compares
    with (630 Pa): the line shows that one and says so."""
    from gelrig.commands.run import fit_lines
    from gelrig.protocols.steps.ramp_hold import fit_brief

    fit = {"G_e": 7146.0, "relax": [{"G": 624.66, "tau": 1413.0}], "terms_resolved": 1,
           "resolved": True, "stderr": {"G_e": 1.7, "G_1": 0.16, "tau_1": 0.49},
           "relax_ramp_corrected": [{"G": 629.98, "tau": 1413.0}]}
    (line,) = fit_lines([fit])
    assert line == ("1-term fit: G_e 7146 +- 1.7 Pa, G_1 630 +- 0.16 Pa (ramp-corrected; "
                    "625 at the hold's start), tau_1 1413 +- 0.49 s")
    assert "G_1 630 +- 0.16 Pa (ramp-corrected; 625 at the hold's start)" in fit_brief(fit)
