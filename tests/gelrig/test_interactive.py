"""Interactive runs through the whole simulated compression rig in virtual time: steps added
one call at a time land in one run directory and see the earlier results; an exception or
Ctrl-C in the block stops motion and records the end; a resume adds steps; reprs are short;
``run.log`` shows on the console (issue 27, item 6)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import gelrig
from gelrig.cli import main
from gelrig.instrument.core.store import read_step
from tests.gelrig.test_cli_text import slow_rig  # the built-in rig, stage capped at 1 mm/s

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = {"name": "A3", "diameter": "18.63 mm"}
SEARCH = {"start": "3 mm", "confirm": 1}
HOLD = {"hold": "30 s", "strain_rate": "0.02 /s", "rate": "100 Hz", "terms": 1}


def _meta(path: Path) -> dict:
    return json.loads((path / "run.json").read_text())


def test_steps_added_one_call_at_a_time_land_in_one_run_and_see_earlier_results(
        tmp_path: Path) -> None:
    out = tmp_path / "runs" / "nb"
    with gelrig.open_rig(slow_rig(tmp_path)) as rig:
        run = rig.run_interactive(name="notebook", out=out, sample=SAMPLE, show=False)
        search = run.step("compression_contact_search", **SEARCH)  # one cell
        assert isinstance(search, gelrig.SearchResult)
        meta = _meta(out)  # recorded at the step's end: a killed kernel leaves it resumable
        assert meta["status"] == "running"
        assert [s["status"] for s in meta["steps"]] == ["completed"]
        # a bad value, or a step the caps refuse, raises before it moves: the run stays open
        with pytest.raises(gelrig.ConfigError, match=r"strain"):
            run.step("ramp_hold", strain="50 %")
        with pytest.raises(gelrig.Refused, match=r"speed .* above .*the run stays open"):
            run.step("compression_contact_search", speed="2 mm/s")
        with pytest.raises(gelrig.GelrigError, match="interactive run is open"):
            rig.run("paper:compression")  # the open run owns the rig
        hold = run.step("ramp_hold", **HOLD)  # a later cell: takes the search's first touch
        result = run.end()
    assert isinstance(hold, gelrig.RampHoldResult)
    assert hold.first_touch_m == search.first_touch_m
    assert hold.depth_m == pytest.approx(0.06 * 18.63e-3)
    assert run.results == [search, hold] and run.dir == out
    assert result.ok and result.name == "notebook" and result.path == out
    # one run directory (beside the runs root's catalog, ADR 0370)
    assert [p.name for p in (tmp_path / "runs").iterdir() if p.name[0] != "."] == ["nb"]
    meta = _meta(out)
    assert meta["status"] == "completed"
    assert meta["protocol"]["protocol"]["interactive"] is True
    assert [(s["index"], s["kind"], s["status"]) for s in meta["steps"]] == [
        (0, "compression_contact_search", "completed"), (1, "ramp_hold", "completed")]
    assert sorted(p.name for p in (out / "steps").iterdir()) == [
        "00_contact_search.h5", "01_ramp_and_hold.h5"]
    assert read_step(out / meta["steps"][1]["file"])["t_s"].size > 3000
    assert meta["steps"][1]["results"]["first_touch_m"] == search.first_touch_m


def test_an_exception_in_the_block_stops_motion_and_ends_the_run_failed_data_kept(
        tmp_path: Path, capsys) -> None:
    out = tmp_path / "nb"
    with gelrig.open_rig("compression") as rig:
        with pytest.raises(ValueError, match="my analysis broke"), \
                rig.run_interactive(out=out, sample=SAMPLE) as run:
            run.step("compression_contact_search", **SEARCH)
            raise ValueError("my analysis broke")
        assert not rig.rig.stage.is_moving()
        assert run.state == "failed" and not run.open
        with pytest.raises(gelrig.RunEnded, match="has ended"):
            run.step("ramp_hold", **HOLD)
    meta = _meta(out)
    assert meta["status"] == "failed"
    assert meta["reason"] == "ValueError: my analysis broke"
    assert meta["safe_state"]["verified"] is True  # stopped, read back, made safe
    assert [s["status"] for s in meta["steps"]] == ["completed"]
    assert read_step(out / meta["steps"][0]["file"])["t_s"].size > 100
    assert "Traceback" not in capsys.readouterr().err

    # resumable like any run: the search is replayed (not run again), the hold added after
    with gelrig.open_rig("compression") as rig, \
            rig.run_interactive(resume=out, show=False) as again:
        assert [type(r) for r in again.results] == [gelrig.SearchResult]
        hold = again.step("ramp_hold", **HOLD)
    assert again.result is not None and again.result.ok
    assert hold.first_touch_m == meta["steps"][0]["results"]["first_touch_m"]
    resumed = _meta(out)
    assert [s["status"] for s in resumed["steps"]] == ["completed", "completed"]
    assert resumed["steps"][0]["started"] == meta["steps"][0]["started"]  # not run again
    assert resumed["steps"][1]["started"] >= meta["steps"][0]["finished"]  # one time base
    assert resumed["resumed"] == ["virtual"]


KILLED = """
import os, sys
import gelrig

rig = gelrig.open_rig("compression")
run = rig.run_interactive(out=sys.argv[1], sample={"diameter": "18.63 mm"}, show=False)
run.step("compression_contact_search", start="3 mm", confirm=1)
os._exit(9)  # the kernel dies: no end, no teardown
"""


def test_a_killed_kernel_leaves_a_run_that_resumes_with_its_steps(tmp_path: Path) -> None:
    out = tmp_path / "nb"
    done = subprocess.run([sys.executable, "-c", KILLED, str(out)], cwd=ROOT, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 9
    meta = _meta(out)
    assert meta["status"] == "running"
    assert [s["status"] for s in meta["steps"]] == ["completed"]
    with gelrig.open_rig("compression") as rig, \
            rig.run_interactive(resume=out, show=False) as run:
        hold = run.step("ramp_hold", **HOLD)
    assert hold.first_touch_m == meta["steps"][0]["results"]["first_touch_m"]
    assert run.state == "completed"
    assert [s["status"] for s in _meta(out)["steps"]] == ["completed", "completed"]


def test_ctrl_c_in_the_block_aborts_and_a_completed_run_can_take_more_steps(
        tmp_path: Path, capsys) -> None:
    out = tmp_path / "nb"
    with gelrig.open_rig("compression") as rig, pytest.raises(KeyboardInterrupt), \
            rig.run_interactive(out=out, sample=SAMPLE, show=False) as run:
        run.step("compression_contact_search", **SEARCH)
        raise KeyboardInterrupt
    meta = _meta(out)
    assert (meta["status"], meta["reason"]) == ("aborted", "interrupted (Ctrl-C)")
    assert meta["safe_state"]["verified"] is True
    # `gelrig resume` and RigSession.resume say in one line how to continue it
    capsys.readouterr()
    assert main(["resume", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is an interactive run" in err
    assert "run_interactive(resume=" in err
    with gelrig.open_rig("compression") as rig:
        with pytest.raises(gelrig.ConfigError, match="is an interactive run"):
            rig.resume(out)
        again = rig.resume_interactive(out, show=False)
        again.step("ramp_hold", **HOLD)
        # the session ends a run left open when it closes
    assert again.state == "completed" and _meta(out)["status"] == "completed"
    assert main(["resume", str(out)]) == 2  # completed too: it says how, not "nothing to do"
    assert "is an interactive run" in capsys.readouterr().err
    with gelrig.open_rig("compression") as rig, \
            rig.run_interactive(resume=out, show=False) as third:  # completed: takes more
        third.step("ramp_hold", name="again", **HOLD)
    assert [s["name"] for s in _meta(out)["steps"]] == ["contact search", "ramp and hold",
                                                         "again"]


def test_ctrl_c_during_a_step_stops_it_records_the_run_aborted_then_raises(
        tmp_path: Path) -> None:
    pressed: list[float] = []

    def ctrl_c_in_the_hold(event: gelrig.Event) -> None:
        if isinstance(event, gelrig.Progress) and event.message == "hold" and not pressed:
            pressed.append(event.t)
            signal.raise_signal(signal.SIGINT)  # handled on the main thread

    out = tmp_path / "nb"
    with gelrig.open_rig("compression") as rig:
        run = rig.run_interactive(out=out, sample=SAMPLE, show=False,
                                  subscribers=[ctrl_c_in_the_hold])
        run.step("compression_contact_search", **SEARCH)
        with pytest.raises(KeyboardInterrupt):
            run.step("ramp_hold", **{**HOLD, "hold": "600 s"})
        assert not rig.rig.stage.is_moving() and run.state == "aborted"
    assert pressed
    meta = _meta(out)
    assert (meta["status"], meta["reason"]) == ("aborted", "aborted by Ctrl-C")
    assert meta["safe_state"]["verified"] is True
    assert [s["status"] for s in meta["steps"]] == ["completed", "aborted"]


def test_a_step_that_trips_ends_the_run_with_run_ended_and_keeps_the_data(
        tmp_path: Path) -> None:
    rig_file = tmp_path / "rig.toml"
    from gelrig.protocols.rigfile import default_rig

    rig_file.write_text(default_rig("compression").read_text().replace(
        'max_force = "2 N"', 'max_force = "50 mN"'))
    out = tmp_path / "nb"
    with gelrig.open_rig(rig_file) as rig:
        with pytest.raises(gelrig.RunEnded, match="interlock force"), \
                rig.run_interactive(out=out, sample=SAMPLE, show=False) as run:
            run.step("compression_contact_search", **SEARCH)
            run.step("ramp_hold", **HOLD)
        assert not rig.rig.stage.is_moving()
    assert run.state == "aborted"
    meta = _meta(out)
    assert meta["status"] == "aborted" and meta["safe_state"]["verified"] is True
    assert [s["status"] for s in meta["steps"]] == ["completed", "aborted"]


# -- concise reprs ---------------------------------------------------------------------------
def _fit(terms: int) -> dict:
    relax = [{"G": 3000.0 / k, "tau": 100.0 * k} for k in range(1, terms + 1)]
    stderr = {"G_e": 12.0, **{f"G_{k}": 30.0 for k in range(1, terms + 1)},
              **{f"tau_{k}": 4.0 for k in range(1, terms + 1)}}
    return {"G_e": 12345.0, "relax": relax, "stderr": stderr, "terms_resolved": terms,
            "resolved": True, "rmse": 1.0, "t0_s": 31.0}


def test_results_print_in_a_line_with_their_key_values() -> None:
    live = [{"elapsed_s": float(k), "G_e": 1e4, "relax": [{"G": 1e3, "tau": 1e2}],
             "stderr": {"G_e": 1.0}, "relative": {}, "forecast": {}} for k in range(500)]
    hold = gelrig.RampHoldResult(6.2e-3, 1.1178e-3, 3.7e-5, 300_000, [_fit(1), _fit(2)],
                                 6.2001e-3, 1.1118e-3, 3000.0, live, "planned", 1e-6)
    text = repr(hold)
    assert len(repr(live)) > 50_000 and len(text) < 300 and "\n" not in text
    for part in ("depth 1.1178 mm", "held 3000 s (planned)", "2-term fit", "G_e 1.234e+04 +- 12 Pa",
                 "G_2 1500 +- 30 Pa", "tau_2 200 +- 4 s", "500 live refits"):
        assert part in text, (part, text)
    assert hold.live_fits is live  # the data stays there
    unresolved = gelrig.RampHoldResult(6.2e-3, 1e-3, 1e-5, 10, [{
        "G_e": 1.0, "relax": [], "resolved": False, "not_resolved": "too short"}])
    assert "fit not resolved: too short" in repr(unresolved)

    search = gelrig.SearchResult(6.19876e-3, 2.5e-6, [6.198e-3, 6.1995e-3], [6.3e-3] * 2, 3e-3)
    assert repr(search) == ("<SearchResult first touch 6.1988 mm, spread 0.0025 mm over 2 "
                            "approaches, tare 3.000 mN>")
    shear = gelrig.ShearSearchResult(1.5e-3, 0.3, 4, 1.2e-3, math.nan, {"gap": [1.0] * 99})
    assert "touch gap 1.2000 mm" in repr(shear) and len(repr(shear)) < 120
    ladder = gelrig.LadderResult(1.2e-3, 0.1, [{"overlap_m": 1e-4}] * 60)
    assert repr(ladder).startswith("<LadderResult 60 passes at touch gap 1.2000 mm")
    run = gelrig.RunResult("failed", "ValueError: x" * 50, Path("runs/a"),
                           [{"status": "completed", "results": {"live_fits": live}},
                            {"status": "failed"}], None, "paper compression")
    text = repr(run)
    assert text.startswith("<RunResult failed 'paper compression' 1 of 2 steps completed, ")
    assert len(text) < 220


def test_a_session_and_an_open_run_print_in_a_line(tmp_path: Path) -> None:
    with gelrig.open_rig("compression") as rig:
        assert repr(rig).startswith("<RigSession compression rig ")
        assert "virtual clock" in repr(rig)
        with rig.run_interactive(name="nb", out=tmp_path / "nb", show=False) as run:
            assert repr(run) == f"<InteractiveRun running 'nb' 0 steps, {tmp_path / 'nb'}>"
            assert "interactive run open in" in repr(rig)
    assert repr(run).startswith("<InteractiveRun completed 'nb' 0 steps")
    assert repr(run.result) == f"<RunResult completed 'nb' 0 steps, {tmp_path / 'nb'}>"


# -- run.log on the console --------------------------------------------------------------------
SCRIPT = '''
import gelrig


@gelrig.protocol(rig="compression", name="search")
def search(run):
    found = run.step("compression_contact_search", start="3 mm", confirm=1)
    run.log(f"LOGGED first touch {found.first_touch_m * 1e3:.3f} mm")
'''


def test_run_log_shows_on_the_console_when_the_run_shows_progress(tmp_path: Path,
                                                                  capsys) -> None:
    script = tmp_path / "search.py"
    script.write_text(SCRIPT)
    with gelrig.open_rig("compression") as rig:
        with rig.run_interactive(out=tmp_path / "nb", sample=SAMPLE) as run:
            run.step("compression_contact_search", **SEARCH)
            run.log("NOTEBOOK line one")
        shown = capsys.readouterr()
        assert "NOTEBOOK line one" in shown.err and "contact search" in shown.err
        quiet = rig.run(script, out=tmp_path / "quiet")  # show=False: the log file only
        assert "LOGGED" not in "".join(capsys.readouterr())
        assert "LOGGED first touch" in (quiet.path / "gelrig.log").read_text()
        rig.run(script, out=tmp_path / "shown", show=True)
        err = capsys.readouterr().err
    assert "NOTEBOOK line one" in (tmp_path / "nb" / "gelrig.log").read_text()
    line = next(x for x in err.splitlines() if "LOGGED" in x)
    assert line.startswith("[") and line.endswith(" mm")  # a whole line of its own
    assert main(["run", str(script), "--no-rehearse", "--out", str(tmp_path / "cli")]) == 0
    assert "LOGGED first touch" in capsys.readouterr().err
