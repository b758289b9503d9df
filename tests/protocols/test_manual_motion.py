"""Manual motions under the interlocks (protocols/manual_motion.py), the load state and unload
of the rigs, and ending a hold early (RunControl.end_hold), on the fakes in virtual time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gelrig.instrument.core.errors import GelrigError
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, Progress, RunState
from gelrig.protocols.manual_motion import Motion, TripNotAcknowledged, run_motion
from gelrig.protocols.rig import (
    LOADED_FORCE,
    CompressionLimits,
    CompressionRig,
    NotHomed,
    ShearLimits,
)
from gelrig.protocols.runner import Runner
from gelrig.protocols.spec import parse_protocol
from tests.doubles import compression_rig, shear_rig

SPEED = 0.5e-3


def move(target: float) -> Motion:
    def start(rig: CompressionRig) -> None:
        rig.move_plate(SPEED, target=target)
    return Motion(start, lambda rig: rig.toward(target))  # type: ignore[arg-type, union-attr]


def test_a_move_into_the_sphere_stops_within_one_sample_of_the_force_limit() -> None:
    limit = 0.3
    rig, stage, force = compression_rig(limits=CompressionLimits(max_force=limit))
    stage.homed = True
    values: list[dict[str, float]] = []
    result = run_motion(rig, "move", move(12e-3), RunControl(), values.append)
    assert result.outcome == "tripped" and result.trip is not None
    assert not stage.is_moving() and "stop" in stage.calls
    # the tripping sample is the first beyond the limit, and the stage stopped within one
    # sample period of it (the fake stops at once)
    t_trip = result.trip.t
    before, at = force.force_at(np.array([t_trip - 1 / 100.0, t_trip]))
    assert before <= limit < at
    z = stage.position()
    step = SPEED / 100.0
    assert values and 0 <= z - values[-1]["position_m"] <= step * (1 + 1e-6)
    assert z < 12e-3


def test_without_a_trip_the_move_ends_at_its_target() -> None:
    rig, stage, _ = compression_rig()
    stage.homed = True
    result = run_motion(rig, "move", move(5e-3), RunControl())
    assert result.outcome == "done" and stage.position() == pytest.approx(5e-3)


def test_a_stop_ends_a_manual_move_at_the_next_block() -> None:
    rig, stage, _ = compression_rig()
    stage.homed = True
    control = RunControl()
    seen: list[float] = []

    def values(v: dict[str, float]) -> None:
        seen.append(v["position_m"])
        if v["position_m"] > 1e-3:
            control.abort("stop pressed")

    result = run_motion(rig, "move", move(5e-3), control, values)
    assert result.outcome == "stopped" and "stop pressed" in result.reason
    assert not stage.is_moving() and stage.position() < 1.5e-3


def test_a_move_away_unloads_past_the_force_limit_but_a_move_toward_is_refused_after_a_trip(
        ) -> None:
    limit = 0.3
    rig, stage, _ = compression_rig(limits=CompressionLimits(max_force=limit))
    stage.homed = True
    assert run_motion(rig, "move", move(12e-3), RunControl()).outcome == "tripped"
    z = stage.position()
    with pytest.raises(TripNotAcknowledged):
        run_motion(rig, "move", move(11e-3), RunControl(), tripped=True)
    assert stage.position() == z  # nothing moved
    result = run_motion(rig, "move", move(z - 1e-3), RunControl(), tripped=True)
    assert result.outcome == "done" and stage.position() == pytest.approx(z - 1e-3)


def test_a_move_before_homing_is_refused_and_nothing_moves() -> None:
    rig, stage, _ = compression_rig()
    with pytest.raises(NotHomed):
        run_motion(rig, "move", move(5e-3), RunControl())
    assert not any(c.startswith("move") for c in stage.calls)


def test_the_load_state_and_the_unload_of_the_compression_rig() -> None:
    rig, stage, force = compression_rig()
    stage.homed = True

    def now() -> dict[str, float]:
        return {"force_N": float(force.force_at(np.array([rig.clock.now()]))[0]),
                "position_m": stage.position()}

    assert rig.load_state(now()) is None
    assert run_motion(rig, "move", move(7e-3), RunControl()).outcome == "done"
    values = now()
    assert values["force_N"] > LOADED_FORCE
    assert "mN on the sample" in str(rig.load_state(values))
    safe = rig.unload()
    assert safe.verified and stage.position() < 6.2e-3  # first touch unknown: all the way
    assert rig.load_state(now()) is None
    rig.first_touch = 6.2e-3  # known: the plate past it counts as loaded, whatever the force
    assert "past first touch" in str(rig.load_state({"force_N": 0.0, "position_m": 6.3e-3}))


def test_the_shear_rig_watches_a_rotation_until_stopped() -> None:
    rig, rheo = shear_rig(limits=ShearLimits(max_torque=1.0))
    control = RunControl()
    polls: list[float] = []

    def values(v: dict[str, float]) -> None:
        polls.append(v["t_s"])
        if len(polls) > 5:
            control.abort("stop pressed")

    motion = Motion(lambda r: r.rotate(1e-4), ends=False)  # type: ignore[union-attr]
    result = run_motion(rig, "rotate", motion, control, values)
    assert result.outcome == "stopped" and len(polls) > 5
    assert not rheo.status().busy


def test_an_instrument_error_in_a_manual_motion_propagates_after_a_stop() -> None:
    rig, rheo = shear_rig()  # the fake refuses gap moves before zero_gap, as the MCR 501 does
    with pytest.raises(GelrigError, match="zero_gap"):
        run_motion(rig, "gap", Motion(lambda r: r.set_gap(5e-3)), RunControl())  # type: ignore
    assert "stop" in rheo.calls


@pytest.mark.parametrize("after", [0.5, 50.0])  # a very short hold must not fail its fit
def test_end_hold_ends_a_hold_early_keeps_its_data_and_the_run_completes(after: float
                                                                          ) -> None:
    rig, _stage, _ = compression_rig()
    control = RunControl()
    bus = EventBus()
    assert not control.end_hold()  # no hold in progress: nothing to end

    def on(event: object) -> None:
        if isinstance(event, Progress) and event.message == "hold" and event.elapsed > after:
            assert control.holding
            control.end_hold()

    bus.subscribe(on)
    spec = parse_protocol({"protocol": {"name": "t", "rig": "compression"}, "step": [
        {"kind": "compression_contact_search", "start": "3 mm", "confirm": 1,
         "tare_time": "0.5 s"},
        {"kind": "ramp_hold", "diameter": "18.63 mm", "hold": "3000 s", "terms": 1,
         "strain_rate": "0.02 /s"}]})
    runner = Runner(rig, spec, bus, control)
    assert runner.run() is RunState.COMPLETED, runner.reason
    held = runner.results[1]["held_s"]
    assert after < held < 3000 and not control.holding
    assert runner.results[1]["samples"] >= math.floor(held * 100)
