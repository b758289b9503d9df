"""The scripting API through the whole simulated rig: scripts run, fail, trip and resume like
protocol files, from Python (``gelrig.open_rig``) and from the CLI (``gelrig run x.py``)."""

from __future__ import annotations

import inspect
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import gelrig
from gelrig.cli import main
from gelrig.instrument.core.store import read_step
from gelrig.protocols.rigfile import default_rig
from gelrig.protocols.steps import KINDS
from tests.gelrig.test_cli_text import slow_rig  # the built-in rig, stage capped at 1 mm/s

ROOT = Path(__file__).resolve().parents[2]

TRAVEL = '''
"""Two plate moves under a custom step kind; the second fails mid-motion while a file named
"fail" lies next to this script."""

import dataclasses
import pathlib
from typing import ClassVar

import gelrig


@dataclasses.dataclass(frozen=True)
class TravelParams(gelrig.StepParams):
    to: float = gelrig.param(gelrig.Field("to", "m", 5e-3, 0.0, 25e-3, display="mm"))
    speed: float = gelrig.param(gelrig.Field("speed", "m/s", 0.5e-3, 0.0, 2.6e-3,
                                             lo_open=True, display="mm/s"))


@dataclasses.dataclass(frozen=True)
class TravelResult(gelrig.StepResult):
    reached_m: float


@gelrig.register_step
class Travel(gelrig.StepDefinition):
    kind: ClassVar[str] = "test_travel"
    rig = gelrig.CompressionRig
    Params, Result = TravelParams, TravelResult
    columns = gelrig.ForceRecorder.columns_published

    def plan(self, params, limits):
        return gelrig.StepPlan(params.to / params.speed, params.to)

    def run(self, ctx, p):
        stage = ctx.rig.stage
        if not stage.status().homed:
            stage.home(wait=True)
        ctx.interlocks = ctx.rig.interlocks()
        rec = gelrig.ForceRecorder(ctx, 100.0)
        rec.start()
        stage.set_velocity(p.speed, ctx.rig.limits.acceleration)
        stage.move_to(p.to, wait=False)
        blocks = 0
        while stage.is_moving():
            rec.read()
            blocks += 1
            if blocks == 20 and p.to > 3e-3 and pathlib.Path(__file__).with_name("fail").exists():
                raise RuntimeError("the script's own bug, mid-motion")
        return TravelResult(stage.position())


@gelrig.protocol(rig="compression", name="two moves")
def two_moves(run):
    run.step("test_travel", name="to 2 mm", to="2 mm")
    run.step("test_travel", name="to 4 mm", to="4 mm")
'''

SEARCH_AND_HOLD = '''
import gelrig


@gelrig.protocol(rig="compression", name="search and hold")
def search_and_hold(run, hold="30 s"):
    found = run.step("compression_contact_search", start="3 mm", confirm=1)
    run.log(f"first touch at {found.first_touch_m * 1e3:.4f} mm")
    run.step("ramp_hold", diameter="18.63 mm", hold=hold, strain_rate="0.02 /s", rate="100 Hz",
             terms=1)
'''


@pytest.fixture
def travel_script(tmp_path: Path):
    path = tmp_path / "travel.py"
    path.write_text(TRAVEL)
    yield path
    KINDS.pop("test_travel", None)


def test_a_script_that_raises_mid_motion_is_stopped_flushed_and_resumable(
        travel_script: Path, tmp_path: Path, capsys) -> None:
    (tmp_path / "fail").touch()
    out = tmp_path / "run"
    # the run-time path: the rehearsal would refuse the script before it moved (issue 27)
    assert main(["run", str(travel_script), "--no-rehearse", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "failed"
    assert meta["reason"].startswith("RuntimeError: the script's own bug, mid-motion (at "
                                     "travel.py:")
    assert meta["safe_state"]["verified"] is True  # motion stopped and read back
    first, second = meta["steps"]
    assert (first["status"], second["status"]) == ("completed", "failed")
    data = read_step(out / second["file"])  # flushed: what was read before the raise
    assert data["t_s"].size >= 20
    assert np.all(np.diff(data["position_m"]) >= -1e-9)
    assert (out / "script" / "travel.py").read_text() == TRAVEL

    (tmp_path / "fail").unlink()  # the bug fixed: resume runs the script again
    assert main(["resume", str(out)]) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "completed"
    assert [s["status"] for s in meta["steps"]] == ["completed", "completed"]
    assert meta["steps"][0]["started"] == first["started"]  # not run again
    assert meta["steps"][1]["results"]["reached_m"] == pytest.approx(4e-3, abs=2e-6)
    assert meta["interrupted_steps"][0]["status"] == "failed"


def test_a_script_run_trips_an_interlock_within_one_sample(tmp_path: Path) -> None:
    rig_file = tmp_path / "rig.toml"
    rig_file.write_text(default_rig("compression").read_text().replace(
        'max_force = "2 N"', 'max_force = "50 mN"'))
    assert 'max_force = "50 mN"' in rig_file.read_text()
    script = tmp_path / "hold.py"
    script.write_text(SEARCH_AND_HOLD)
    with gelrig.open_rig(rig_file) as rig:
        result = rig.run(script, out=tmp_path / "run")
    assert result.state == "aborted"
    assert result.reason.startswith("interlock force")
    assert result.safe_state is not None and result.safe_state["verified"]
    force = read_step(result.path / result.steps[1]["file"])["force_N"]
    beyond = np.flatnonzero(force > 0.05)
    assert beyond.size == 1 and beyond[0] == force.size - 1  # recorded up to the first beyond
    # continued from Python on the rig with its usual 2 N limit: the hold runs, the search
    # is not run again
    with gelrig.open_rig("compression") as rig:
        resumed = rig.resume(result.path)
    assert resumed.ok, resumed.reason
    assert resumed.steps[0]["started"] == result.steps[0]["started"]
    assert resumed.results("ramp and hold")["held_s"] == pytest.approx(30.0, abs=0.01)


def test_a_script_runs_from_python_and_its_results_come_back(tmp_path: Path) -> None:
    script = tmp_path / "hold.py"
    script.write_text(SEARCH_AND_HOLD)
    seen: list[gelrig.Event] = []
    with gelrig.open_rig("compression", clock="virtual") as rig:
        result = rig.run(gelrig.load_protocol(script), out=tmp_path / "run",
                         subscribers=[seen.append])
    assert result.ok, result.reason
    hold = result.results("ramp and hold")
    assert hold["depth_m"] == pytest.approx(0.06 * 18.63e-3)
    assert hold["first_touch_m"] == pytest.approx(6.2e-3, abs=5e-6)
    assert any(isinstance(e, gelrig.FitUpdate) for e in seen)  # the live fit's events too
    log = (result.path / "gelrig.log").read_text()
    assert "gelrig.script: first touch at 6.19" in log or "first touch at 6.20" in log


def test_leaving_a_session_by_an_error_stops_the_motion_first(capsys) -> None:
    with pytest.raises(RuntimeError, match="oops"), gelrig.open_rig("compression") as rig:
        rig.home()
        rig.rig.stage.set_velocity(1e-3, 4e-3)
        rig.rig.stage.move_to(5e-3, wait=False)  # left moving
        assert rig.rig.stage.is_moving()
        raise RuntimeError("oops")
    err = capsys.readouterr().err
    assert "motion stopped (verified)" in err


def test_leaving_a_session_by_an_error_after_a_press_unloads_until_the_load_is_gone(
        capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    """First touch unknown (a manual press 2.4 mm into the sphere, no search): the safe stop
    goes back until the load cell reads below the loaded level, not a fixed 2 mm (issue 32:
    it said 'retracted to 6.600 mm' with the plate still 0.4 mm in)."""
    import numpy as np

    from gelrig.simulators import kdc101 as kdc101_sim

    sims: list[Any] = []
    real_register = kdc101_sim.register

    def register(sim: Any, name: str) -> str:
        sims.append(sim)
        return real_register(sim, name)

    monkeypatch.setattr(kdc101_sim, "register", register)
    touch = 6.2e-3  # the built-in rig's [simulator] first_touch
    with pytest.raises(RuntimeError, match="script bug"), \
            gelrig.open_rig("compression") as rig:
        rig.home()
        rig.move_plate(1e-3, to=touch + 2.4e-3, confirm=True)  # before a contact search
        assert rig.readings()["force_N"] > 0.1  # pressed in
        raise RuntimeError("script bug")
    err = capsys.readouterr().err
    line = next(t for t in err.splitlines() if t.startswith("gelrig: "))
    assert line.startswith("gelrig: motion stopped (verified); plate retracted to "), line
    where, force = line.removeprefix("gelrig: motion stopped (verified); plate retracted to "
                                     ).split(" mm, ")
    assert float(where) * 1e-3 < touch - 1e-4  # clear of the sphere
    assert float(force.removesuffix(" mN read back")) < 5.0  # below the loaded level
    sim = sims[0]  # the simulator itself: where its plate is now
    plate = float(sim.positions_at(np.array([sim.clock.now()]))[0]) - sim.config.home_offset_m
    assert plate == pytest.approx(float(where) * 1e-3, abs=2e-6)
    assert plate < touch


def test_a_manual_move_in_a_session_trips_like_a_step(tmp_path: Path, capsys) -> None:
    rig_file = tmp_path / "rig.toml"
    rig_file.write_text(default_rig("compression").read_text().replace(
        'max_force = "2 N"', 'max_force = "50 mN"'))
    with gelrig.open_rig(rig_file) as rig:
        with pytest.raises(gelrig.NotHomed):
            rig.move_plate(1e-3, to=12e-3, confirm=True)
        rig.home()
        with pytest.raises(gelrig.InterlockTripped, match="interlock force"):
            rig.move_plate(0.3e-3, to=12e-3, confirm=True)
        values = rig.readings()
        assert values["moving"] == 0.0
        assert 6.4e-3 < values["position_m"] < 7.5e-3  # stopped at ~50 mN, past first touch
        assert capsys.readouterr().err == ""
    # left normally with the plate in the sphere: unloaded first (first touch unknown here,
    # so all the way back), and said
    err = capsys.readouterr().err
    # stopped at the 50 mN limit within a sample (the load then relaxes a little)
    loaded = err.split("the sample was loaded (", 1)[1].split(" mN on the sample", 1)[0]
    assert 40 < float(loaded) < 52, err
    assert "motion stopped (verified); plate retracted to 0.000 mm" in err


def test_gelrig_plan_rehearses_a_script_and_bad_references_are_one_line(
        tmp_path: Path, capsys) -> None:
    script = tmp_path / "hold.py"
    script.write_text(SEARCH_AND_HOLD)
    assert main(["plan", str(script)]) == 0
    out = capsys.readouterr().out
    assert "decided by the script as it runs" in out
    assert "1. ramp and hold: completed" in out and "rehearsal passed" in out
    assert main(["plan", str(script), "--param", "hold='45 s'"]) == 0
    longer = capsys.readouterr().out
    assert "Params:   hold = '45 s'" in longer

    def hold_step(text: str) -> float:
        return float(re.search(r"1\. ramp and hold: completed in ([\d.]+) s", text)[1])

    assert hold_step(longer) - hold_step(out) == pytest.approx(15.0, abs=0.05)
    assert main(["plan", str(script), "--param", "hld=3"]) == 2
    assert "[script parameter] hld" not in (err := capsys.readouterr().err) and \
        "hold.py takes hold" in err
    assert main(["plan", "paper:compression", "--param", "hold=3"]) == 2
    assert "only scripts (.py) take parameters" in capsys.readouterr().err
    assert main(["run", str(tmp_path / "nope.py")]) == 2
    assert "no such Python file" in capsys.readouterr().err
    shear = ROOT / "protocols" / "rigs" / "shear.toml"
    assert main(["run", str(script), "--rig", str(shear)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "needs a compression rig" in err


def test_the_public_surface_is_listed_once_and_documented() -> None:
    page = (ROOT / "docs" / "scripting.md").read_text()
    for name in gelrig.__all__:
        value = getattr(gelrig, name)
        assert inspect.getdoc(value), f"gelrig.{name} has no docstring"
        assert f"`{name}`" in page, f"docs/scripting.md does not list gelrig.{name}"
    assert sorted(dir(gelrig)) == sorted([*gelrig.__all__, "__version__"])


def test_resuming_from_python_a_run_json_without_its_protocol_is_one_line(tmp_path) -> None:
    from gelrig.instrument.core.store import RunDirectory

    run = RunDirectory.create(tmp_path / "run", {"status": "failed"})
    with gelrig.open_rig("compression") as rig, pytest.raises(
            gelrig.ConfigError, match=r"run\.json must hold the protocol table to resume"):
        rig.resume(run.path)


# -- one exit-code rule: a step refused before it moves ----------------------------------------
REFUSED_SCRIPT = '''
import gelrig


@gelrig.protocol(rig="compression", name="refused")
def refused(run, speed="0.5 mm/s", strain=0.04):
    run.step("compression_contact_search", name="probe", confirm=0, speed=speed)
    run.step("ramp_hold", diameter="18.63 mm", name="deep", strain=strain, hold="1 s",
             rate="100 Hz", terms=1)


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
'''


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args], cwd=cwd, text=True, capture_output=True,
                          timeout=240, env={**os.environ, "COLUMNS": "200"})


@pytest.mark.slow
@pytest.mark.parametrize(("command", "param", "line"), [
    # a speed above the rig's max_velocity (a cap of the built rig), `gelrig run`
    (("-m", "gelrig.cli", "run", "s.py"), 'speed="1.31 mm/s"',
     "gelrig run: step 0 (probe): speed 1.31 mm/s above the stage's max_velocity 1 mm/s "
     "([stage] max_velocity); refused before anything moves"),
    # a value out of its field's range, through `python s.py` (script_main)
    (("s.py",), 'speed="2.5 mm/s"',
     'gelrig run: step 0 (probe): speed = "2.5 mm/s": allowed (0, 2.3] mm/s (at s.py:7); '
     "refused before anything moves"),
])
def test_a_script_step_refused_before_anything_moved_exits_2_with_one_line_and_no_folder(
        tmp_path: Path, command: tuple[str, ...], param: str, line: str) -> None:
    (tmp_path / "s.py").write_text(REFUSED_SCRIPT)
    done = run_cli(*command, "--rig", str(slow_rig(tmp_path)), "--param", param,
                   "--out", "runs/new/run", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [line]
    assert not (tmp_path / "runs").exists()  # the run folder and the parents made for it


@pytest.mark.slow
def test_a_script_step_refused_after_earlier_steps_moved_keeps_their_data_and_exits_2(
        tmp_path: Path) -> None:
    (tmp_path / "s.py").write_text(REFUSED_SCRIPT)
    # the run-time path (without the rehearsal, which refuses it before anything moves)
    done = run_cli("-m", "gelrig.cli", "run", "s.py", "--param", "strain=0.2", "--no-rehearse",
                   "--out", "run", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    faults = [t for t in done.stderr.splitlines() if t.startswith("FAULT")]
    assert len(faults) == 1, done.stderr
    assert faults[0].startswith(
        "FAULT LimitError: step 1 (deep): depth 3.7260 mm beyond the overlap limit 2.5 mm "
        "([limits] max_overlap); refused before it moved (the data of the 1 step before it "
        "are kept); motion stopped (verified); plate retracted to "), faults[0]
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["status"] == "refused"
    assert [s["status"] for s in meta["steps"]] == ["completed"]
    assert read_step(tmp_path / "run" / meta["steps"][0]["file"])["t_s"].size > 100


def test_the_api_raises_refused_and_leaves_no_folder_when_nothing_moved(tmp_path: Path
                                                                        ) -> None:
    script = tmp_path / "s.py"
    script.write_text(REFUSED_SCRIPT)
    fast = tmp_path / "fast.toml"
    fast.write_text('[protocol]\nname = "fast"\nrig = "compression"\n[[step]]\n'
                    'kind = "compression_contact_search"\nname = "probe"\nspeed = "1.31 mm/s"\n')
    with gelrig.open_rig(slow_rig(tmp_path)) as rig:
        for protocol in (fast, gelrig.load_protocol(script).with_params(speed="1.31 mm/s")):
            with pytest.raises(gelrig.Refused) as refused:
                rig.run(protocol, out=tmp_path / "new" / "run")
            assert str(refused.value) == (
                "step 0 (probe): speed 1.31 mm/s above the stage's max_velocity 1 mm/s "
                "([stage] max_velocity); refused before anything moves")
            assert isinstance(refused.value, gelrig.ConfigError)
            assert not (tmp_path / "new").exists()
        result = rig.run(gelrig.load_protocol(script).with_params(strain=0.2),
                         out=tmp_path / "deep")
    assert result.state == "refused"
    assert "refused before it moved (the data of the 1 step before it are kept)" in \
        result.reason
    assert result.safe_state is not None and result.safe_state["verified"] is True
    assert [s["status"] for s in result.steps] == ["completed"]
    assert result.steps[0]["samples"] > 100
