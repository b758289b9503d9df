"""Bring-up rehearsed on the twin (issue 30): the twin plays the operator, answering from a
hidden truth the rig file does not know; the confirmed rig file must find it."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from gelrig.bringup import runner
from gelrig.bringup.operator import TwinOperator
from gelrig.cli import main
from gelrig.instrument.core.units import to_si

RIG = """\
[rig]
kind = "compression"
name = "Bring-up twin"

[stage]
transport = "simulator"
counts_per_mm = 34554.96   # UNVERIFIED (ADR 0003): 34304 in pylablib
max_position = "12 mm"
direction = "forward_is_negative"

[force]
transport = "simulator"

[force.chain]
rated_output = "2 mV/V"    # UNVERIFIED (ADR 0010)
gain = 1000

[limits]
max_force = "2 N"

[simulator]
counts_per_mm = 34304
rated_output = "2.06 mV/V"
noise = "0.35 mN"
seed = 3
"""


def _rig(folder: Path, **truth: str) -> Path:
    text = RIG + "".join(f"{k} = {v}\n" for k, v in truth.items())
    path = folder / "rig.toml"
    path.write_text(text)
    return path


def _confirmed(path: Path) -> dict:
    return tomllib.loads(path.read_text())


@pytest.mark.slow
def test_bringup_by_the_twin_finds_the_hidden_truth_and_the_result_plans(tmp_path, capsys):
    rig = _rig(tmp_path)
    out = tmp_path / "confirmed.toml"
    assert main(["bringup", str(rig), "--operator", "twin", "--out", str(out)]) == 0
    root = _confirmed(out)
    stage, chain = root["stage"], root["force"]["chain"]
    assert stage["counts_per_mm"] == pytest.approx(34304, rel=1e-3)
    assert stage["counts_per_mm"] != pytest.approx(34554.96, rel=1e-3)
    assert to_si(chain["rated_output"], "V/V", "rated_output") == pytest.approx(2.06e-3,
                                                                               rel=5e-3)
    assert to_si(chain["noise"], "N", "noise") == pytest.approx(0.35e-3, rel=0.15)
    assert stage["direction"] == "forward_is_negative"
    text = out.read_text()
    # provenance beside each value, the old value kept, UNVERIFIED gone, the truth untouched
    assert "counts_per_mm = 34554.96" not in text.split("[simulator]")[0].replace(
        "# was: counts_per_mm = 34554.96", "")
    assert "# was: counts_per_mm = 34554.96" in text
    assert "# was: rated_output = \"2 mV/V\"" in text
    assert "UNVERIFIED" not in text
    line = next(ln for ln in text.splitlines() if ln.startswith("counts_per_mm ="))
    assert all(f in line for f in ("# confirmed: ", "| operator: twin |", "| method: ",
                                   "| u: "))
    assert text.split("[simulator]")[1] == RIG.split("[simulator]")[1]
    assert rig.read_text() == RIG  # the user's file is not touched
    capsys.readouterr()
    assert main(["plan", "paper:compression", "--rig", str(out)]) == 0
    assert "rehearsal passed" in capsys.readouterr().out


def test_an_inverted_direction_is_found(tmp_path):
    rig = _rig(tmp_path, direction="+1")
    only = ("stage.scale", "stage.backlash", "stage.velocity", "loadcell")  # home, direction
    outcome = runner.run(rig, lambda r, c, s: runner.twin_operator(r, c, s, declines=only))
    found = {item.key: item.value for item in outcome.accepted}
    assert found["direction"] == "forward_is_positive"
    assert any("INVERTED" in line for line in outcome.findings)
    assert outcome.written == runner.default_out(rig)
    assert tomllib.loads(outcome.written.read_text())["stage"]["direction"] == \
        "forward_is_positive"


def test_a_declined_step_moves_and_writes_nothing(tmp_path):
    rig = _rig(tmp_path)
    made: list[TwinOperator] = []
    start: list[float] = []

    def operator(r, c, s):
        made.append(runner.twin_operator(r, c, s, declines=(
            "stage.home", "loadcell.calibration", "write [force.chain] offset")))
        start.append(float(r.twin.stage.position_at(c.now())))
        return made[0]

    outcome = runner.run(rig, operator)
    op = made[0]
    # home declined: no stage routine ran, the stage never moved
    assert op.twin.stage.position_at(op.clock.now()) == pytest.approx(start[0], abs=1e-12)
    # no gain, no rated output; white noise: no correlated part
    assert {item.key for item in outcome.accepted} == {"noise", "noise_drift"}
    assert {item.key for item in outcome.declined} == {"offset"}
    assert outcome.written is not None
    text = outcome.written.read_text()
    assert "counts_per_mm = 34554.96   # UNVERIFIED" in text  # untouched
    assert 'rated_output = "2 mV/V"    # UNVERIFIED' in text
    assert "offset" not in text.split("[force.chain]")[1].split("[limits]")[0]


def test_nothing_accepted_writes_no_file(tmp_path):
    rig = _rig(tmp_path)
    out = tmp_path / "never.toml"
    declines = ("stage.home", "loadcell.calibration", "write")
    outcome = runner.run(rig, lambda r, c, s: runner.twin_operator(r, c, s,
                                                                   declines=declines), out)
    assert outcome.accepted == [] and outcome.declined and outcome.written is None
    assert not out.exists()


def test_twin_operator_on_a_real_rig_is_one_line_exit_2(tmp_path, capsys):
    rig = tmp_path / "real.toml"
    rig.write_text(RIG.replace('[stage]\ntransport = "simulator"',
                               '[stage]\ntransport = "serial"\naddress = "/dev/null-kdc"'))
    code = main(["bringup", str(rig), "--operator", "twin"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "Traceback" not in err
    assert err.startswith("gelrig: ") or "--operator" in err
    assert "--operator = twin" in err or "--operator" in err


def test_the_console_operator_declining_everything_writes_nothing(tmp_path, monkeypatch,
                                                                  capsys):
    rig = _rig(tmp_path)
    asked: list[str] = []
    monkeypatch.setattr("builtins.input", lambda prompt: (asked.append(prompt), "n")[1])
    out = tmp_path / "never.toml"
    assert main(["bringup", str(rig), "--name", "ana", "--out", str(out), "--wire-log"]) == 0
    printed = capsys.readouterr().out
    assert "Nothing written." in printed and not out.exists()
    assert asked[0] == "Go ahead with stage.home? [y/n] "
    assert {"Go ahead with loadcell.noise? [y/n] ",
            "Go ahead with loadcell.calibration? [y/n] "} <= set(asked)
    # identify (no motion, no question) reached the controller, and the wire log has it
    log = tmp_path / "never.wire.jsonl"
    assert log.is_file() and '"i":"kdc101"' in log.read_text()


def test_a_sample_left_on_the_plate_trips_the_interlock_and_the_scale_is_not_written(tmp_path):
    """The operator forgot the sample: the scale's steps press the sphere, the force
    interlock trips, the stop is delivered and read back, and no scale is proposed."""
    rig = tmp_path / "rig.toml"
    rig.write_text(RIG.replace('max_force = "2 N"', 'max_force = "0.05 N"')
                   .replace("seed = 3", 'seed = 3\nfirst_touch = "2.5 mm"'))
    made: list[TwinOperator] = []

    def operator(r, c, s):
        made.append(runner.twin_operator(r, c, s, declines=("loadcell", "write")))
        return made[0]

    outcome = runner.run(rig, operator)
    said = "\n".join(made[0].said or [])
    assert "STOPPED: move to" in said and "tripped" in said
    assert "stop" in said.split("STOPPED:")[1].lower()
    assert {item.key for item in outcome.declined} == {"direction"}  # found before the trip
    assert outcome.written is None


def test_the_velocity_run_times_the_acceleration_reached(tmp_path):
    """Issue 30: velocity and acceleration limits reached. The full-speed move's duration
    bounds the acceleration (its ramps), which must hold the rig file's request."""
    rig = _rig(tmp_path)
    only = ("stage.scale", "stage.backlash", "loadcell")
    outcome = runner.run(rig, lambda r, c, s: runner.twin_operator(r, c, s, declines=only))
    (line,) = [f for f in outcome.findings if f.startswith("acceleration:")]
    low, high = (float(v) for v in line.split()[1:4:2])
    assert low <= 4.0 <= high and line.endswith("reached"), line  # 4 mm/s^2 requested


def test_an_acceleration_the_move_did_not_reach_is_said():
    from gelrig.bringup.stage import _acceleration_line

    t = np.arange(0.0, 4.0, 0.01)  # 2.3 mm/s over 5.75 mm took 4 s: 1.5 s of ramps
    line = _acceleration_line(t, 5.75e-3, 2.3e-3, 4e-3)
    assert "NOT as requested" in line and line.startswith("acceleration: 1.5")
