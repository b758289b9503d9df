"""End to end: a frozen instrument server cannot hang ``gelrig run`` (issue 12).

The rig's DAQ is a separate ``gelrig sim serve usb6001`` process that the test freezes with
SIGSTOP during the hold; two Ctrl-C then end the run within seconds with exit code 3, the safe
stop done from the main thread (the stage, simulated in-process, is stopped, read back and
retracted), one line naming the log file, and run.json saying so.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from gelrig.instrument.core.store import RunDirectory

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs SIGSTOP")

RIG = """
[rig]
kind = "compression"
name = "stage simulated in-process, DAQ served by another process"
[stage]
transport = "simulator"
[force]
transport = "grpc"
address = "grpc://127.0.0.1:{port}"
[force.chain]
rated_output = "2 mV/V"
excitation = "5 V"
gain = 1000
"""

PROTOCOL = """
[protocol]
name = "hold"
rig = "compression"
[[step]]
kind = "ramp_hold"
diameter = "18.63 mm"
first_touch = "3 mm"
strain = 0.01
strain_rate = "0.05 /s"
hold = "300 s"
tare_time = "0.2 s"
terms = 1
"""

ROOT = Path(__file__).resolve().parents[2]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_for(predicate: Callable[[], Any], timeout: float) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError("condition not met in time")


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


@contextlib.contextmanager
def _daq_server(port: int) -> Iterator[subprocess.Popen[bytes]]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "gelrig.cli", "sim", "serve", "usb6001",
                             "--port", str(port)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=env)
    try:
        _wait_for(lambda: _listening(port), 60)
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGCONT)
            proc.kill()
        proc.wait(30)


def test_two_ctrl_c_end_a_run_frozen_in_an_instrument_call(tmp_path: Path) -> None:
    port = _free_port()
    rig = tmp_path / "rig.toml"
    rig.write_text(RIG.format(port=port))
    protocol = tmp_path / "hold.toml"
    protocol.write_text(PROTOCOL)
    out = tmp_path / "run"
    run = RunDirectory(out)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1"}

    def holding() -> bool:
        try:
            if run.read_metadata()["steps"][0]["status"] != "running":
                return False
            return bool(run.read_step(0)["t_s"].size > 100)  # ~1 s of the hold, flushed
        except Exception:
            return False

    with _daq_server(port) as server:
        proc = subprocess.Popen(
            [sys.executable, "-m", "gelrig.cli", "run", str(protocol), "--rig", str(rig),
             "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            stdin=subprocess.DEVNULL, env=env)
        try:
            _wait_for(holding, 90)
            server.send_signal(signal.SIGSTOP)  # the DAQ freezes mid-hold
            time.sleep(1.0)
            proc.send_signal(signal.SIGINT)
            time.sleep(0.5)
            start = time.monotonic()
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=40)
            took = time.monotonic() - start
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(30)
    assert proc.returncode == 3, stderr
    assert took < 25.0
    text = stdout + stderr
    assert "Traceback" not in text
    log = out / "gelrig.log"
    named = [line for line in text.splitlines() if str(log) in line]
    assert len(named) == 1, text
    line = named[0]
    assert line.startswith("ABORTED: aborted by Ctrl-C"), line
    assert "motion stopped (verified); plate retracted to 1.000 mm" in line
    meta = run.read_metadata()
    assert meta["status"] == "aborted"
    assert meta["safe_state"]["verified"] is True
    assert meta["safe_state"]["line"] in line
    assert "safe stop" in log.read_text()
