"""The watchdog's line says what the run's thread was doing when it expired: stuck in an
instrument call (a frozen instrument), or in the script's own code that has not returned
(a step kind of the user's in a loop of its own); the host's end from outside says the
same, and a run thread that comes back after that end does not turn it into a completion."""

from __future__ import annotations

import re
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import pytest

from gelrig.instrument.core.fields import Field, param
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols import host as hosting
from gelrig.protocols.context import StepContext
from gelrig.protocols.events import Event, EventBus, RunState
from gelrig.protocols.host import RunHost
from gelrig.protocols.origin import is_instrument, is_users, stuck_site, stuck_words
from gelrig.protocols.rig import CompressionLimits, CompressionRig
from gelrig.protocols.runner import Runner
from gelrig.protocols.script import Run, protocol
from gelrig.protocols.steps import register
from gelrig.protocols.steps.base import StepDefinition, StepParams, StepPlan, StepResult
from tests.doubles import compression_rig
from tests.protocols.test_safe_stop import HOLD
from tests.protocols.test_safe_stop import protocol as protocol_of

RELEASE = threading.Event()  # ends the spin of the step kind below


@dataclass(frozen=True)
class SpinParams(StepParams):
    limit: float = param(Field("limit", "s", 10.0, 0.0, 60.0))


@dataclass(frozen=True)
class SpinResult(StepResult):
    spun_s: float


class Spin(StepDefinition[CompressionRig, SpinParams, SpinResult]):
    """A step kind of the user's that loops in its own code (wall time) until released."""

    kind: ClassVar[str] = "test_watchdog_spin"
    rig = CompressionRig
    Params, Result = SpinParams, SpinResult
    columns: ClassVar[dict[str, str]] = {}

    def plan(self, params: SpinParams, limits: Any) -> StepPlan:
        return StepPlan(0.0, 0.0, ["spin"])

    def run(self, ctx: StepContext[CompressionRig], params: SpinParams) -> SpinResult:
        start = time.monotonic()
        while not RELEASE.is_set() and time.monotonic() - start < params.limit:  # SPIN LINE
            pass  # SPIN LINE
        return SpinResult(time.monotonic() - start)


#: Where the spin is when the watchdog looks: ``test_watchdog_site.py:(58|59)``.
SPIN_AT = "{}:({})".format(Path(__file__).name, "|".join(
    str(i) for i, line in enumerate(Path(__file__).read_text().splitlines(), 1)
    if line.endswith("# SPIN LINE")))


@pytest.fixture(autouse=True)
def spin_kind() -> Any:
    register(Spin)
    RELEASE.clear()
    yield
    RELEASE.set()


@protocol(rig="compression")
def spinner(run: Run) -> None:
    run.step("test_watchdog_spin", limit="10 s")
    run.step("test_watchdog_spin", limit="10 s")


def test_the_sites_of_code() -> None:
    import gelrig.drivers.kdc101.driver as driver
    import gelrig.protocols.runner as runner
    import gelrig.simulators.kdc101.device as device

    assert is_instrument(driver.__file__) and is_instrument(device.__file__)
    assert not is_instrument(runner.__file__) and not is_users(runner.__file__)
    assert is_users(__file__) and not is_users(threading.__file__)
    assert stuck_site(None) == ("", "")
    assert stuck_words("", "") == "an instrument may be frozen"


def test_the_watchdog_says_the_scripts_own_code_has_not_returned() -> None:
    rig, _stage, _force = compression_rig(limits=CompressionLimits(watchdog=0.3))
    runner = Runner(rig, spinner)
    bus_seen: list[Event] = []
    runner.bus.subscribe(bus_seen.append)

    def release_after_expiry() -> None:
        deadline = time.monotonic() + 10.0
        while not runner.control.abort_requested and time.monotonic() < deadline:
            time.sleep(0.02)
        RELEASE.set()

    threading.Thread(target=release_after_expiry, daemon=True).start()
    assert runner.run() is RunState.FAILED
    assert re.fullmatch(rf"watchdog: no data for [\d.]+ s \(limit 0.3 s\); the script's own "
                        rf"code \({SPIN_AT}\) has not returned", runner.reason), runner.reason
    assert "instrument" not in runner.reason


def test_the_watchdog_says_an_instrument_call_is_stuck() -> None:
    rig, _stage, force = compression_rig(limits=CompressionLimits(watchdog=0.3))
    runner = Runner(rig, protocol_of("compression", HOLD))

    def freeze_in_hold(event: Event) -> None:
        if rig.clock.now() > 60.0 and not force.faults.frozen.is_set() and \
                not runner.control.abort_requested:
            force.faults.freeze()

    def thaw_after_expiry() -> None:
        deadline = time.monotonic() + 10.0
        while not runner.control.abort_requested and time.monotonic() < deadline:
            time.sleep(0.02)
        force.faults.thaw()

    runner.bus.subscribe(freeze_in_hold)
    threading.Thread(target=thaw_after_expiry, daemon=True).start()
    assert runner.run() is RunState.FAILED
    assert "; stuck in an instrument call (tests/doubles.py:" in runner.reason, runner.reason
    assert "script" not in runner.reason


def test_a_run_ended_from_outside_stays_ended_when_its_thread_comes_back(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The spin outlasts the grace: the host ends the run from outside (safe stop, run.json
    failed); then the spin returns and the script asks for its next step: the run stays
    failed, with the watchdog's reason."""
    from gelrig.terminal import run_in_terminal

    monkeypatch.setattr(hosting, "GRACE", 0.3)
    rig, _stage, _force = compression_rig(limits=CompressionLimits(watchdog=0.3))
    run = RunDirectory.create(tmp_path / "run", {})
    codes: list[int] = []

    def release_after_the_end() -> None:
        deadline = time.monotonic() + 15.0
        while host.outside_end is None and time.monotonic() < deadline:
            time.sleep(0.02)
        RELEASE.set()

    with RunHost(rig, spinner, run, bus=EventBus()) as host:
        threading.Thread(target=release_after_the_end, daemon=True).start()
        state = run_in_terminal(host, show=False, exit=codes.append)
        assert host.wait(5.0)  # the thread came back (and started no step)
    assert codes == [1] and state is RunState.FAILED and host.state is RunState.FAILED
    meta = run.read_metadata()
    assert meta["status"] == "failed"
    assert re.search(rf"the script's own code \({SPIN_AT}\) has not returned$",
                     meta["reason"]), meta["reason"]
    assert len(meta["steps"]) == 1  # the second spin was never started
