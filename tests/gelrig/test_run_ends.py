"""How a run that ends short reaches the person: ``RigSession.run`` returns a failed RunResult
on the watchdog (no exception) and raises KeyboardInterrupt only after a Ctrl-C stopped the
run; ``gelrig run`` prints the watchdog's FAULT line naming the script's own code and exits 1.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import gelrig
from gelrig.protocols import host as hosting
from gelrig.protocols.events import Event, Progress
from gelrig.protocols.steps import register
from tests.protocols.test_watchdog_site import RELEASE, SPIN_AT, Spin, spinner
from tests.rigs import compression_rig_with
from tests.samples import SHORT_COMPRESSION


def rig_with_watchdog(tmp_path: Path, seconds: str) -> Path:
    return compression_rig_with(tmp_path, f'watchdog = "{seconds}"')


@pytest.fixture
def spin_kind() -> Iterator[None]:
    register(Spin)
    RELEASE.clear()
    yield
    RELEASE.set()


def test_the_api_returns_a_failed_result_on_the_watchdog(
        tmp_path: Path, spin_kind: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hosting, "GRACE", 0.3)
    with gelrig.open_rig(rig_with_watchdog(tmp_path, "0.5 s")) as session:
        result = session.run(spinner, out=tmp_path / "run")  # no exception
        RELEASE.set()
    assert result.state == "failed"
    assert re.search(rf"^watchdog: no data for .*; the script's own code \({SPIN_AT}\) has "
                     "not returned$", result.reason), result.reason
    assert result.safe_state is not None and result.safe_state["verified"] is True


def test_ctrl_c_in_the_api_stops_the_run_then_raises(tmp_path: Path) -> None:
    (tmp_path / "p.toml").write_text(SHORT_COMPRESSION.format(hold="600 s"))
    pressed: list[float] = []

    def ctrl_c_in_the_hold(event: Event) -> None:
        if isinstance(event, Progress) and event.message == "hold" and not pressed:
            pressed.append(event.t)
            signal.raise_signal(signal.SIGINT)  # handled on the main thread

    with pytest.raises(KeyboardInterrupt), gelrig.open_rig("compression") as session:
        session.run(tmp_path / "p.toml", out=tmp_path / "run",
                    subscribers=[ctrl_c_in_the_hold])
    assert pressed
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["status"] == "aborted" and run["reason"] == "aborted by Ctrl-C"
    assert run["safe_state"]["verified"] is True


SPIN_SCRIPT = '''
import time
from dataclasses import dataclass
from typing import ClassVar

import gelrig


@dataclass(frozen=True)
class SpinParams(gelrig.StepParams):
    pass


@dataclass(frozen=True)
class SpinResult(gelrig.StepResult):
    pass


@gelrig.register_step
class CliSpin(gelrig.StepDefinition):
    kind: ClassVar[str] = "test_cli_spin"
    rig = gelrig.CompressionRig
    Params, Result = SpinParams, SpinResult
    columns: ClassVar[dict[str, str]] = {}

    def plan(self, params, limits):
        return gelrig.StepPlan(0.0, 0.0, ["spin"])

    def run(self, ctx, params):
        end = time.monotonic() + 60.0
        while time.monotonic() < end:  # SPIN
            pass  # SPIN
        return SpinResult()


@gelrig.protocol(rig="compression", name="spin")
def spin(run: gelrig.Run) -> None:
    run.step("compression_contact_search", confirm=0)
    run.step("test_cli_spin")
'''


@pytest.mark.slow
def test_gelrig_run_names_the_scripts_own_code_on_the_watchdog(tmp_path: Path) -> None:
    (tmp_path / "spin.py").write_text(SPIN_SCRIPT)
    lines = "|".join(str(i) for i, text in enumerate(SPIN_SCRIPT.splitlines(), 1)
                     if text.endswith("# SPIN"))
    done = subprocess.run(
        [sys.executable, "-m", "gelrig.cli", "run", "spin.py", "--rig",
         str(rig_with_watchdog(tmp_path, "1 s")), "--out", "run"], cwd=tmp_path,
        capture_output=True, text=True, timeout=120, env={**os.environ, "COLUMNS": "200"})
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    faults = [line for line in done.stderr.splitlines() if line.startswith("FAULT")]
    assert len(faults) == 1, done.stderr
    assert re.fullmatch(rf"FAULT: watchdog: no data for [\d.]+ s \(limit 1 s\); the script's "
                        rf"own code \(spin\.py:({lines})\) has not returned; motion stopped "
                        rf"\(verified\); .*; details: .*gelrig\.log", faults[0]), faults[0]
