"""The rehearsal (protocols/rehearsal.py) and the caps every command goes through."""

from __future__ import annotations

import dataclasses

import pytest

from instrument.errors import LimitError
from instrument.stage import StageConfig
from protocols.events import RunState
from protocols.rehearsal import rehearse
from protocols.rig import CompressionRig, ShearLimits
from protocols.runner import Runner
from protocols.spec import parse_protocol
from tests.doubles import FakeForceSensor, FakeStage, compression_rig, shear_rig


def protocol(rig: str, *steps: dict) -> object:
    return parse_protocol({"protocol": {"name": "t", "rig": rig}, "step": list(steps)})


SEARCH = {"kind": "compression_contact_search", "name": "find", "start": "3 mm", "confirm": 0,
          "tare_time": "0.5 s"}
HOLD = {"kind": "ramp_hold", "name": "hold", "hold": "20 s", "terms": 1,
        "strain_rate": "0.02 /s"}


def capped_rig(max_velocity: float) -> tuple[CompressionRig, FakeStage]:
    from instrument.clock import VirtualClock

    clock = VirtualClock()
    stage = FakeStage(clock, dataclasses.replace(StageConfig(), max_velocity_m_s=max_velocity))
    force = FakeForceSensor(clock, stage, 6.2e-3)
    return CompressionRig(stage, force, clock, simulated=True), stage


def test_a_speed_above_the_cap_is_refused_before_anything_moves() -> None:
    rig, stage = capped_rig(1e-3)
    runner = Runner(rig, protocol("compression", {**SEARCH, "speed": "1.31 mm/s"}))
    assert runner.run() is RunState.FAILED
    assert "step 0 (find)" in runner.reason and "max_velocity 1 mm/s" in runner.reason
    assert "1.31 mm/s" in runner.reason
    assert stage.calls == []  # not even homed
    assert stage.position() == 0.0


def test_a_manual_move_above_the_cap_is_refused() -> None:
    rig, stage = capped_rig(1e-3)
    with pytest.raises(LimitError, match="max_velocity"):
        rig.move_plate(1.5e-3, target=2e-3)
    with pytest.raises(LimitError, match="max_position"):
        rig.stage.move_to(13e-3)
    assert stage.calls == []


def test_ramp_hold_without_a_search_is_refused_before_anything_moves() -> None:
    rig, stage, _ = compression_rig()
    report = rehearse(rig, protocol("compression", HOLD))
    assert not report.ok
    assert report.failure().startswith("step 0 (hold): ramp_hold needs first_touch")
    assert stage.calls == []


def test_the_arm_speed_cap_and_the_overlap_cap_hold_on_every_command() -> None:
    rig, _rheo = shear_rig(ShearLimits(max_overlap=0.5e-3))
    with pytest.raises(LimitError, match="max_speed"):
        rig.rotate(2 * rig.rheometer.config.max_speed)
    rig.zero_gap()
    rig.know_touch_gap(3e-3)
    with pytest.raises(LimitError, match=r"overlap limit 0\.5 mm"):
        rig.rheometer.set_gap(2.4e-3)
    rig.rheometer.set_gap(2.6e-3)  # within: goes through
    assert rig.rheometer.gap() == pytest.approx(2.6e-3)


def test_a_ladder_deeper_than_the_overlap_cap_is_refused_before_it_moves() -> None:
    rig, _rheo = shear_rig()
    ladder = {"kind": "speed_ladder", "name": "ladder", "touch_gap": "3 mm",
              "centre_angle": 0.8, "first_overlap": "1.5 mm", "overlaps": 1}
    report = rehearse(rig, protocol("shear", ladder))
    assert report.failure().startswith("step 0 (ladder): overlap 1.5 mm beyond the overlap "
                                       "limit 1.2 mm")


def test_rehearsal_counts_lab_time_samples_bytes_and_travel() -> None:
    rig, _stage, _ = compression_rig()
    report = rehearse(rig, protocol("compression", SEARCH, HOLD))
    assert report.ok, report.reason
    search, hold = report.steps
    assert search.status == hold.status == "completed"
    assert report.total == pytest.approx(search.duration + hold.duration, abs=1e-9)
    assert hold.samples >= 20 * 100  # 20 s hold at 100 Hz, plus ramp and retract
    assert hold.bytes == hold.samples * 8 * len(hold.columns)
    assert search.travel > 3e-3  # moved to the start, then probed
    _lo, hi = hold.ranges["position_m"]
    assert hi == pytest.approx(6.2e-3 + 0.06 * 18.63e-3, abs=2e-5)
    assert report.hits == []


def test_an_interlock_trip_is_reported_with_step_and_time() -> None:
    from protocols.rig import CompressionLimits

    rig, _, _ = compression_rig(limits=CompressionLimits(max_force=0.05))
    report = rehearse(rig, protocol("compression", SEARCH, HOLD))
    assert report.state is RunState.ABORTED
    assert [h.index for h in report.hits] == [1]
    assert "force" in report.hits[0].what
    assert report.failure().startswith("step 1 (hold) at ")
