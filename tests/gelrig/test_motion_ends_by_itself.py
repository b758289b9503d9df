"""A gelrig killed mid-motion leaves no motion running for longer than the bound (ADR 0201).

Each test runs a twin as its own ``gelrig sim serve`` process on the real clock, lets a gelrig
process (the KDC101 driver in a small script; a whole ``gelrig run`` of a speed ladder) move
the axis at constant speed, SIGKILLs that process, then reads the twin with a client gelrig
did not write (pylablib's KinesisMotor; pyvisa) over a fresh connection: the axis must be at
rest within ``motion_bound`` (2 s) of the kill plus a margin, where a motion that ends by
itself within that bound puts it, and stay there. With the unbounded commands gelrig used
before (MOT_MOVE_VELOCITY, ``:ROT[dir;rpm]``) both would still be moving.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gelrig.instrument.core.store import RunDirectory
from tests.served import serve

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs SIGKILL")

ROOT = Path(__file__).resolve().parents[2]
BOUND_S = 2.0  # [stage] / [rheometer] motion_bound, default
MARGIN_S = 0.5  # reconnecting and polling the twin after the kill
SPEED = 1e-3  # m/s, both axes


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1"}


def _until(check: Callable[[], Any], timeout: float, what: str) -> Any:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = check()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


@contextlib.contextmanager
def _process(argv: list[str], **kwargs: Any) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen(argv, text=True, env=_env(), cwd=ROOT, stdin=subprocess.DEVNULL,
                            **kwargs)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(30)
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()


# ---- the stage ---------------------------------------------------------------------------

#: A gelrig process: the KDC101 driver starts a velocity move (towards the software limit, 12
#: mm away) and reports (monotonic time, position, renewals) while it polls, as a step does.
STAGE_SCRIPT = """
import sys, time
from gelrig.drivers.kdc101 import KDC101
stage = KDC101(sys.argv[1]).open()
stage.set_velocity(float(sys.argv[2]), 4e-3)
stage.move_velocity(+1)
while True:
    position = stage.position()
    print(f"{time.monotonic():.6f} {position:.9f} {stage.renewals}", flush=True)
    time.sleep(0.05)
"""

kinesis = pytest.importorskip("pylablib.devices.Thorlabs.kinesis", exc_type=ImportError)


def _open_motor(address: str) -> Any:
    """pylablib on the twin as soon as the twin takes a new client (it serves one at a time)."""
    def attempt() -> Any:
        motor = None
        try:
            motor = kinesis.KinesisMotor(("serial", address), scale="step")
            motor.get_position()
            return motor
        except Exception:
            if motor is not None:
                with contextlib.suppress(Exception):
                    motor.close()
            return None
    return _until(attempt, 5.0, "the KDC101 twin to take a new client")


def test_a_stage_moving_when_gelrig_is_killed_stops_within_the_bound() -> None:
    with serve("kdc101", "--clock", "real") as twin:
        address = f"socket://{twin.host}:{twin.port}"
        with _process([sys.executable, "-c", STAGE_SCRIPT, address, str(SPEED)],
                      stdout=subprocess.PIPE, stderr=subprocess.PIPE) as gelrig:
            assert gelrig.stdout is not None
            reports: list[tuple[float, float, int]] = []
            while not reports or reports[-1][0] - reports[0][0] < 2.5:  # cruising, renewed
                line = gelrig.stdout.readline()
                assert line, gelrig.stderr.read() if gelrig.stderr else "gelrig ended"
                t, p, n = line.split()
                reports.append((float(t), float(p), int(n)))
            gelrig.send_signal(signal.SIGKILL)
            t_kill = time.monotonic()
            gelrig.wait(10)
        t_last, p_last, renewals = reports[-1]
        recent = [r for r in reports if r[0] > t_last - 1.0]
        speed = (recent[-1][1] - recent[0][1]) / (recent[-1][0] - recent[0][0])
        assert speed == pytest.approx(SPEED, rel=0.03)  # at constant speed when killed
        assert renewals >= 3  # the velocity move went out as renewed segments
        p_kill = p_last + SPEED * (t_kill - t_last)

        motor = _open_motor(address)
        try:
            cpm = 34554.96e3  # the twin's counts per metre
            seen = _until(lambda: None if motor.is_moving() else time.monotonic(),
                          BOUND_S + 3.0, "the stage to stop")
            p_stop = motor.get_position() / cpm
            time.sleep(max(0.0, t_kill + BOUND_S + 1.0 - time.monotonic()))
            assert not motor.is_moving()
            assert motor.get_position() / cpm == pytest.approx(p_stop, abs=1e-9)  # stays
        finally:
            motor.close()
    # At rest: seen so through the twin within the bound plus the margin ...
    assert seen - t_kill <= BOUND_S + MARGIN_S
    # ... where a motion that ends by itself within the bound puts it: at most v * bound past
    # where the stage was at the kill, far short of the velocity move's end at 12 mm.
    travelled = p_stop - p_kill
    accel = 4e-3
    stopped_after = travelled / SPEED + SPEED / (2 * accel)  # cruise, then brake to rest
    print(f"\nstage: killed at {p_kill * 1e3:.3f} mm, at rest at {p_stop * 1e3:.3f} mm "
          f"({travelled * 1e3:.3f} mm later), {stopped_after:.2f} s after the kill; seen at "
          f"rest {seen - t_kill:.2f} s after it")
    assert -0.05e-3 <= travelled <= SPEED * BOUND_S
    assert stopped_after <= BOUND_S + 0.1
    assert p_stop < 10e-3


# ---- the rheometer -------------------------------------------------------------------------

RIG = """
[rig]
kind = "shear"
name = "MCR 501 twin served by another process"
[rheometer]
transport = "visa"
address = "TCPIP0::127.0.0.1::{port}::SOCKET"
arm = "27 mm"
max_speed = "5 mm/s"
"""

#: One clockwise pass at 1 mm/s over 16 mm (16 s) from where the arm starts (angle 0), with
#: the ladder told a touch gap 3 mm above the twin's: the spheres never meet.
PROTOCOL = """
[protocol]
name = "one pass"
rig = "shear"
[[step]]
kind = "speed_ladder"
touch_gap = "6 mm"
centre_angle = {centre}
overlaps = 1
first_overlap = "0.1 mm"
speeds = ["1 mm/s"]
travel = "16 mm"
wait = "1 s"
interval = "0.1 s"
read_period = "0.5 s"
"""


def _query(res: Any, line: str) -> str:
    return str(res.query(line))


def _open_rheometer(resource: str) -> Any:
    """pyvisa on the twin once it takes a new client (the killed one's line is released)."""
    import pyvisa

    rm = pyvisa.ResourceManager("@py")

    def attempt() -> Any:
        res = rm.open_resource(resource, read_termination="\r\n", write_termination="\r\n",
                               timeout=2000)
        try:
            if _query(res, ":STAT[?]").startswith(":STAT["):
                return res
        except Exception:
            pass
        res.close()
        return None

    return rm, _until(attempt, 5.0, "the MCR 501 twin to take a new client")


def test_an_arm_turning_when_gelrig_run_is_killed_stops_within_the_bound(tmp_path: Path) -> None:
    arm = 0.027
    (tmp_path / "one_pass.toml").write_text(PROTOCOL.format(centre=8e-3 / arm))
    with serve("mcr501", "--clock", "real") as twin:
        (tmp_path / "rig.toml").write_text(RIG.format(port=twin.port))
        run = RunDirectory(tmp_path / "run")

        def turning() -> dict[str, np.ndarray] | None:
            try:
                data = run.read_step(0)
            except Exception:
                return None
            theta = data["theta_m"][data["pass"] == 0]  # the clockwise leg
            # turning for 2 s (the leg's first points were taken while the lift moved)
            return data if theta.size > 20 and np.all(np.diff(theta[-21:]) > 0) else None

        with _process([sys.executable, "-m", "gelrig.cli", "run",
                       str(tmp_path / "one_pass.toml"), "--rig", str(tmp_path / "rig.toml"),
                       "--clock", "real", "--out", str(run.path)],
                      stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) as gelrig:
            data = _until(turning, 60.0, "the pass to be recorded")
            gelrig.send_signal(signal.SIGKILL)
            t_kill = time.monotonic()
            gelrig.wait(10)
        mine = data["pass"] == 0
        t, theta = data["t_s"][mine], data["theta_m"][mine]
        speed = (theta[-1] - theta[-11]) / (t[-1] - t[-11])
        assert speed == pytest.approx(SPEED, rel=1e-3)  # at constant speed when killed
        theta_kill = theta[-1] + SPEED * (t_kill - t[-1])  # run time is time.monotonic()

        rm, res = _open_rheometer(f"TCPIP0::{twin.host}::{twin.port}::SOCKET")
        try:
            def at_rest() -> float | None:
                mode, flags = _query(res, ":STAT[?]")[6:-1].split(";")
                return time.monotonic() if mode == "IDLE" and not int(flags, 16) & 0x08 \
                    else None

            seen = _until(at_rest, BOUND_S + 3.0, "the arm to stop")
            angle = float(_query(res, ":ANG[?]")[5:-1])
            time.sleep(max(0.0, t_kill + BOUND_S + 1.0 - time.monotonic()))
            assert at_rest()
            assert float(_query(res, ":ANG[?]")[5:-1]) == angle  # stays
        finally:
            res.close()
            rm.close()
    theta_stop = np.radians(angle) * arm
    travelled = theta_stop - theta_kill
    print(f"\narm: killed at theta {theta_kill * 1e3:.3f} mm, at rest at {theta_stop * 1e3:.3f}"
          f" mm ({travelled * 1e3:.3f} mm later, ~{travelled / SPEED:.2f} s of turning); seen"
          f" at rest {seen - t_kill:.2f} s after the kill")
    assert seen - t_kill <= BOUND_S + MARGIN_S
    # the rotation ran out at most 1.5 s (its segment) after the kill, then ramped to rest
    assert -0.05e-3 <= travelled <= SPEED * BOUND_S
    assert theta_stop < 16e-3  # far short of the pass's end
