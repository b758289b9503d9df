"""Step logic on fakes of the instrument contracts (tests/doubles.py): milliseconds, not seconds.

The HIL tests (test_compression_run, test_shear_run) drive the same steps through the real
drivers and simulators; these pin down what each step decides, with a rig whose truth the
test sets.
"""

from __future__ import annotations

import pytest

from gelrig.instrument.physics.contact import Material
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, InterlockTrip, RunState
from gelrig.protocols.rig import CompressionLimits
from gelrig.protocols.runner import Runner
from gelrig.protocols.spec import parse_protocol
from tests.doubles import compression_rig, shear_rig


def protocol(rig: str, *steps: dict) -> object:
    return parse_protocol({"protocol": {"name": "t", "rig": rig}, "step": list(steps)})


SEARCH = {"kind": "compression_contact_search", "start": "3 mm", "confirm": 1,
          "tare_time": "0.5 s"}


@pytest.mark.parametrize("touch", [4.0e-3, 6.2e-3, 9.5e-3])
def test_contact_search_finds_the_touch_it_is_given(touch: float) -> None:
    rig, stage, _ = compression_rig(first_touch=touch)
    runner = Runner(rig, protocol("compression", SEARCH))
    assert runner.run() is RunState.COMPLETED, runner.reason
    result = runner.results[0]
    assert result["first_touch_m"] == pytest.approx(touch, abs=5e-6)
    assert len(result["estimates_m"]) == 2
    assert "home" in stage.calls  # an unhomed stage is homed before anything else


def test_contact_search_gives_up_after_max_travel() -> None:
    rig, stage, _ = compression_rig(first_touch=11.9e-3)
    runner = Runner(rig, protocol("compression", {**SEARCH, "max_travel": "2 mm"}))
    assert runner.run() is RunState.FAILED
    assert "no contact within 2 mm" in runner.reason
    assert not stage.is_moving()


def test_ramp_hold_reaches_its_depth_and_fits_the_modulus() -> None:
    material = Material.of(7146.0, [(630.0, 100.0)])
    rig, stage, _ = compression_rig(material=material)
    hold = {"kind": "ramp_hold", "diameter": "18.63 mm", "hold": "400 s", "terms": 1,
            "strain_rate": "0.02 /s"}
    runner = Runner(rig, protocol("compression", SEARCH, hold))
    assert runner.run() is RunState.COMPLETED, runner.reason
    result = runner.results[1]
    assert result["first_touch_m"] == pytest.approx(runner.results[0]["first_touch_m"])
    assert result["depth_m"] == pytest.approx(0.06 * 18.63e-3)
    fit = result["fits"][0]
    assert fit["G_e"] == pytest.approx(7146.0, rel=0.05)
    assert stage.position() == pytest.approx(result["first_touch_m"] - 2e-3, abs=1e-9)


def test_ramp_hold_without_first_touch_fails_before_moving() -> None:
    rig, stage, _ = compression_rig()
    runner = Runner(rig, protocol("compression", {"kind": "ramp_hold", "diameter": "18.63 mm"}))
    assert runner.run() is RunState.REFUSED
    assert "first_touch" in runner.reason
    assert not any(c.startswith("move_to") for c in stage.calls)


def test_force_interlock_stops_the_stage_and_ends_the_run() -> None:
    limits = CompressionLimits(max_force=0.05)
    rig, stage, _ = compression_rig(limits=limits)
    bus = EventBus()
    trips: list[InterlockTrip] = []
    bus.subscribe(lambda e: trips.append(e) if isinstance(e, InterlockTrip) else None)
    runner = Runner(rig, protocol("compression", SEARCH, {"kind": "ramp_hold",
                                                          "diameter": "18.63 mm", "hold": "1 s"}),
                    bus)
    assert runner.run() is RunState.ABORTED
    assert runner.reason.startswith("interlock force")
    assert trips and trips[0].interlock == "force" and trips[0].value > 0.05
    assert "stop" in stage.calls and not stage.is_moving()


def test_abort_stops_motion_before_the_next_block() -> None:
    rig, stage, _ = compression_rig()
    control = RunControl()
    bus = EventBus()
    bus.subscribe(lambda e: control.abort("test") if stage.is_moving() else None)
    runner = Runner(rig, protocol("compression", SEARCH), bus, control)
    assert runner.run() is RunState.ABORTED
    assert "stop" in stage.calls and not stage.is_moving()


SHEAR_SEARCH = {"kind": "shear_contact_search", "safe_gap": "4 mm", "sweep": "70 mm"}


@pytest.mark.parametrize(("touch_gap", "lower_angle"), [(3e-3, 0.8), (2.2e-3, -0.4)])
def test_shear_search_finds_the_touch_gap_and_the_lower_sphere(touch_gap: float,
                                                               lower_angle: float) -> None:
    rig, rheo = shear_rig(touch_gap=touch_gap, lower_angle=lower_angle, g=24e3)
    search = SHEAR_SEARCH
    runner = Runner(rig, protocol("shear", search))
    assert runner.run() is RunState.COMPLETED, runner.reason
    result = runner.results[0]
    assert result["touch_gap_m"] == pytest.approx(touch_gap, abs=0.05e-3)
    assert result["lower_sphere_angle_rad"] == pytest.approx(lower_angle, abs=0.01)
    assert rheo.calls[0] == "zero_gap"
