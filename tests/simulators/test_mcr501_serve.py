"""`gelrig sim serve mcr501`: a standalone simulator in paced time, reached with pyvisa-py."""

from __future__ import annotations

import argparse
import re
import shlex
import subprocess
import sys
import time

import pytest

from gelrig.drivers.mcr501 import open_resource_manager
from gelrig.instrument.core.errors import ConfigError
from gelrig.simulators.mcr501 import serve


def test_serve_in_paced_time_answers_pyvisa() -> None:
    argv = shlex.split("sim serve mcr501 --port 0 --clock paced:100 --duration 1.5 --seed 3")
    proc = subprocess.Popen(
        [sys.executable, "-m", "gelrig.cli", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        m = re.search(r"listening on 127\.0\.0\.1:(\d+) \(paced:100\); VISA resource (\S+)", first)
        assert m, first
        rm = open_resource_manager("@py")
        res = rm.open_resource(
            m.group(2), read_termination="\r\n", write_termination="\r\n", timeout=2000
        )
        try:
            assert res.query("#VERS[?]") == "#VERS[MCR501;SN80000000;03.40]"
            assert res.query(":RUN[1]") == ":RUN[OK]"
            t0 = time.monotonic()
            time.sleep(0.3)
            header = res.query("#DATA[?]")
            elapsed = time.monotonic() - t0
            count = int(re.fullmatch(r"#DATA\[(\d+);0\]", header).group(1))  # type: ignore[union-attr]
            for _ in range(count):
                assert res.read().startswith(":MEAS[")
            # 100 virtual seconds per real second, one point per virtual second
            assert 100 * 0.3 - 2 <= count <= 100 * elapsed + 2
        finally:
            res.close()
            rm.close()
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()


def test_serve_refuses_a_virtual_clock() -> None:
    parser = argparse.ArgumentParser()
    serve.add_arguments(parser)
    args = parser.parse_args(["--clock", "virtual", "--port", "0"])
    with pytest.raises(ConfigError, match="--clock"):
        serve.run(args)
    args = parser.parse_args(["--touch-gap", "3 N"])
    with pytest.raises(ConfigError, match="--touch-gap"):
        serve.build(args)
    args = parser.parse_args(["--lower-angle", "45 deg", "--touch-gap", "2.5 mm"])
    _, sim = serve.build(args)
    assert sim.config.lower_angle == pytest.approx(0.785398, rel=1e-5)
    assert sim.config.touch_gap == pytest.approx(2.5e-3)
