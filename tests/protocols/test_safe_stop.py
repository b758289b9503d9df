"""The verified safe end state (ADR 0070) and the watchdog, on the fakes of tests/doubles.py."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import Event, EventBus, Fault, RunState, SafeStopped
from gelrig.protocols.host import RunHost
from gelrig.protocols.rig import CompressionLimits, ShearLimits
from gelrig.protocols.runner import Runner
from gelrig.protocols.safestop import Unanswered, bounded
from gelrig.protocols.spec import parse_protocol
from gelrig.protocols.watchdog import Watchdog
from tests.doubles import compression_rig, shear_rig

TOUCH = 6.2e-3
HOLD = {"kind": "ramp_hold", "diameter": "18.63 mm", "first_touch": "6.2 mm", "hold": "100 s",
        "terms": 1,
        "strain_rate": "0.02 /s", "tare_time": "0.2 s"}


def protocol(rig: str, *steps: dict) -> object:
    return parse_protocol({"protocol": {"name": "t", "rig": rig}, "step": list(steps)})


def events_of(bus: EventBus) -> list[Event]:
    seen: list[Event] = []
    bus.subscribe(seen.append)
    return seen


def safe_of(seen: list[Event]) -> SafeStopped:
    found = [e for e in seen if isinstance(e, SafeStopped)]
    assert len(found) == 1
    return found[0]


def test_bounded_returns_raises_and_gives_up() -> None:
    assert bounded(lambda: 7, 1.0, "x") == 7
    with pytest.raises(ZeroDivisionError):
        bounded(lambda: 1 / 0, 1.0, "x")
    gate = threading.Event()
    start = time.monotonic()
    with pytest.raises(Unanswered, match=r"no answer within 0\.2 s"):
        bounded(lambda: gate.wait(10), 0.2, "x")
    assert time.monotonic() - start < 2.0
    gate.set()


def test_fault_with_a_working_stop_is_verified_and_retracts_from_first_touch() -> None:
    rig, stage, force = compression_rig()
    force.faults.fail_at = 50.0  # the force input's link drops mid-hold
    bus = EventBus()
    seen = events_of(bus)
    runner = Runner(rig, protocol("compression", HOLD), bus)
    assert runner.run() is RunState.FAILED
    assert "Disconnected" in runner.reason
    safe = safe_of(seen).state
    assert safe.verified
    assert safe.line() == "motion stopped (verified); plate retracted to 4.200 mm"
    assert not stage.is_moving()
    assert stage.position() == pytest.approx(TOUCH - 2e-3, abs=1e-9)
    kinds = [type(e).__name__ for e in seen[-5:]]
    assert kinds == ["Fault", "SafeStopped", "StepFinished", "StateChanged", "Finished"]


def test_retract_distance_comes_from_the_rig_file_and_zero_only_stops() -> None:
    rig, stage, force = compression_rig(limits=CompressionLimits(retract_on_fault=0.0))
    force.faults.fail_at = 50.0
    runner = Runner(rig, protocol("compression", HOLD))
    assert runner.run() is RunState.FAILED
    assert runner.safe_state is not None and runner.safe_state.verified
    line = runner.safe_state.line()
    assert line == "motion stopped (verified)"
    assert stage.position() > TOUCH  # still pressed in: the rig file asked only to stop
    assert "retract_on_fault" in CompressionLimits.specs()


def test_a_stop_that_fails_is_not_claimed() -> None:
    rig, stage, force = compression_rig()
    force.faults.fail_at = 50.0
    stage.faults.fail_at = 50.0  # the stage's link drops too (and cannot be reopened)
    runner = Runner(rig, protocol("compression", HOLD))
    assert runner.run() is RunState.FAILED
    safe = runner.safe_state
    assert safe is not None and not safe.verified
    assert not safe.axes[0].stop_sent  # a write on a lost link is not a stop sent
    assert safe.line() == "STOP NOT SENT: stage link lost and not reopened - check the rig"
    assert "motion stopped" not in safe.line()


def test_a_frozen_stage_cannot_hang_the_safe_stop() -> None:
    rig, stage, _ = compression_rig()
    stage.faults.freeze()
    try:
        start = time.monotonic()
        safe = rig.safe_stop("test", budget=1.0)
        assert time.monotonic() - start < 3.0
    finally:
        stage.faults.thaw()
    assert not safe.verified
    assert safe.line().startswith("STOP SENT, NOT CONFIRMED: stage unreachable")
    assert "no answer within" in safe.axes[0].errors[0]


def test_a_stop_that_raises_but_reads_back_stopped_is_verified_by_the_read_back() -> None:
    rig, stage, _ = compression_rig()
    stage.faults.fail_stop = True
    safe = rig.safe_stop("test")
    assert safe.axes[0].stopped and safe.axes[0].errors  # the error is kept for run.json
    assert safe.line().startswith("motion stopped (verified)")


def test_an_abort_mid_hold_stops_and_retracts() -> None:
    rig, _stage, _ = compression_rig()
    control = RunControl()
    bus = EventBus()
    seen = events_of(bus)

    def abort_in_hold(event: Event) -> None:
        if rig.clock.now() > 60.0:
            control.abort("stop pressed")

    bus.subscribe(abort_in_hold)
    runner = Runner(rig, protocol("compression", HOLD), bus, control)
    assert runner.run() is RunState.ABORTED
    assert safe_of(seen).state.line() == "motion stopped (verified); plate retracted to 4.200 mm"
    assert not any(isinstance(e, Fault) for e in seen)


def test_an_interlock_trip_retracts_the_plate() -> None:
    rig, stage, _ = compression_rig(limits=CompressionLimits(max_force=0.05))
    runner = Runner(rig, protocol("compression", HOLD))
    assert runner.run() is RunState.ABORTED
    assert runner.reason.startswith("interlock force")
    assert runner.safe_state is not None and runner.safe_state.verified
    assert stage.position() == pytest.approx(TOUCH - 2e-3, abs=1e-9)


def test_shear_fault_stops_the_arm_and_lifts_it() -> None:
    rig, rheo = shear_rig()
    rheo.zero_gap()
    rheo.set_gap(2.5e-3)
    rheo.rotate(1e-3)
    safe = rig.safe_stop("test")
    assert safe.verified
    # the touch gap is not known: the normal force read back says the arm is clear
    assert safe.line() == ("motion stopped (verified); arm lifted to gap 4.500 mm, normal force "
                           "0 mN read back")
    assert rheo.gap() == pytest.approx(4.5e-3)
    assert rheo.calls[-2:] == ["stop", "set_gap 0.0045"]
    rig.know_touch_gap(3e-3)
    rheo.set_gap(2.5e-3)
    assert rig.safe_stop("test").line() == "motion stopped (verified); arm lifted to gap 4.500 mm"


def test_shear_only_stops_when_asked_or_unreferenced() -> None:
    rig, rheo = shear_rig(limits=ShearLimits(lift_on_fault=0.0))
    rheo.zero_gap()
    rheo.rotate(1e-3)
    assert rig.safe_stop("test").line() == "motion stopped (verified)"
    rig, rheo = shear_rig()
    rheo.rotate(1e-3)  # no zero_gap: a gap move is not possible, stopping is all
    assert rig.safe_stop("test").line() == "motion stopped (verified)"
    rheo.faults.unreachable = True  # its link is lost (Disconnected) and cannot be reopened
    assert rig.safe_stop("test").line() == (
        "STOP NOT SENT: rheometer link lost and not reopened - check the rig")


def test_run_json_records_the_safe_state(tmp_path: Path) -> None:
    rig, _stage, force = compression_rig()
    force.faults.fail_at = 50.0
    run = RunDirectory.create(tmp_path / "run", {})
    with RunHost(rig, protocol("compression", HOLD), run) as host:
        assert host.run() is RunState.FAILED
    meta = run.read_metadata()
    assert meta["status"] == "failed"
    safe = meta["safe_state"]
    assert safe["verified"] is True
    assert safe["line"] == "motion stopped (verified); plate retracted to 4.200 mm"
    stage_facts = safe["instruments"]["stage"]
    assert stage_facts["stopped"] is True and stage_facts["safe_ok"] is True
    assert stage_facts["position"] == pytest.approx(TOUCH - 2e-3, abs=1e-9)


def test_watchdog_faults_a_run_whose_data_stops(tmp_path: Path) -> None:
    rig, _stage, force = compression_rig(limits=CompressionLimits(watchdog=0.3))
    control = RunControl()
    bus = EventBus()
    seen = events_of(bus)

    def freeze_in_hold(event: Event) -> None:
        if rig.clock.now() > 60.0 and not force.faults.frozen.is_set() and \
                not control.abort_requested:
            force.faults.freeze()

    def thaw_after_expiry() -> None:  # the frozen read returns once the watchdog has fired
        deadline = time.monotonic() + 10.0
        while not control.abort_requested and time.monotonic() < deadline:
            time.sleep(0.02)
        force.faults.thaw()

    bus.subscribe(freeze_in_hold)
    threading.Thread(target=thaw_after_expiry, daemon=True).start()
    run = RunDirectory.create(tmp_path / "run", {})
    start = time.monotonic()
    with RunHost(rig, protocol("compression", HOLD), run, bus=bus, control=control) as host:
        assert host.run() is RunState.FAILED
    assert time.monotonic() - start < 8.0
    assert host.reason.startswith("watchdog: no data for")
    faults = [e for e in seen if isinstance(e, Fault)]
    assert [f.kind for f in faults] == ["WatchdogExpired"]
    assert safe_of(seen).state.verified
    meta = run.read_metadata()
    assert meta["faults"][0]["kind"] == "WatchdogExpired"
    assert meta["safe_state"]["verified"] is True


def test_watchdog_is_quiet_while_events_flow_or_paused() -> None:
    now = [0.0]
    control = RunControl()
    dog = Watchdog(control, 5.0, wall=lambda: now[0])
    now[0] = 4.0
    assert not dog.check()
    dog(Event(0.0))
    now[0] = 8.0
    assert not dog.check()
    from gelrig.protocols.events import StateChanged

    dog(StateChanged(0.0, RunState.RUNNING, RunState.PAUSED))
    now[0] = 100.0
    assert not dog.check()
    dog(StateChanged(0.0, RunState.PAUSED, RunState.RUNNING))
    now[0] = 106.0
    assert dog.check() and control.abort_requested and control.fault_kind == "WatchdogExpired"


def test_cli_ends_a_run_stuck_in_a_frozen_instrument(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The watchdog fires, the run thread cannot see it (its read is frozen): the host ends
    the run from outside (safe stop, run.json), the terminal prints the line and exits 1."""
    from gelrig.protocols import host as hosting
    from gelrig.terminal import run_in_terminal

    monkeypatch.setattr(hosting, "GRACE", 0.3)
    rig, _stage, force = compression_rig(limits=CompressionLimits(watchdog=0.3))
    bus = EventBus()

    def freeze_in_hold(event: Event) -> None:
        if rig.clock.now() > 60.0 and not force.faults.frozen.is_set():
            force.faults.freeze()

    bus.subscribe(freeze_in_hold)
    run = RunDirectory.create(tmp_path / "run", {})
    codes: list[int] = []
    log_path = tmp_path / "run" / "gelrig.log"
    start = time.monotonic()
    try:
        with RunHost(rig, protocol("compression", HOLD), run, bus=bus) as host:
            state = run_in_terminal(host, show=False, exit=codes.append)
        took = time.monotonic() - start
        assert force.faults.blocked.is_set()  # really stuck in the read
    finally:
        force.faults.thaw()
    assert codes == [1] and state is RunState.FAILED
    assert took < 8.0
    meta = run.read_metadata()
    assert meta["status"] == "failed"
    assert meta["reason"].startswith("watchdog: no data for")
    assert meta["faults"][0]["kind"] == "WatchdogExpired"
    assert meta["safe_state"]["line"] == "motion stopped (verified); plate retracted to 4.200 mm"
    assert "the run thread is stuck here" in log_path.read_text()
