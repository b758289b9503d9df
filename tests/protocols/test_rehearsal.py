"""The rehearsal (protocols/rehearsal.py) and the caps every command goes through."""

from __future__ import annotations

import dataclasses

import pytest

from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.errors import LimitError
from gelrig.protocols.events import EventBus, RunState
from gelrig.protocols.rehearsal import rehearse
from gelrig.protocols.rig import CompressionRig, ShearLimits
from gelrig.protocols.runner import Runner
from gelrig.protocols.spec import parse_protocol
from tests.doubles import FakeForceSensor, FakeStage, compression_rig, shear_rig


def protocol(rig: str, *steps: dict) -> object:
    return parse_protocol({"protocol": {"name": "t", "rig": rig}, "step": list(steps)})


SEARCH = {"kind": "compression_contact_search", "name": "find", "start": "3 mm", "confirm": 0,
          "tare_time": "0.5 s"}
HOLD = {"kind": "ramp_hold", "diameter": "18.63 mm", "name": "hold", "hold": "20 s", "terms": 1,
        "strain_rate": "0.02 /s"}


def capped_rig(max_velocity: float) -> tuple[CompressionRig, FakeStage]:
    from gelrig.instrument.core.clock import VirtualClock

    clock = VirtualClock()
    stage = FakeStage(clock, dataclasses.replace(StageConfig(), max_velocity_m_s=max_velocity))
    force = FakeForceSensor(clock, stage, 6.2e-3)
    return CompressionRig(stage, force, clock, simulated=True), stage


def test_a_speed_above_the_cap_is_refused_before_anything_moves() -> None:
    rig, stage = capped_rig(1e-3)
    runner = Runner(rig, protocol("compression", {**SEARCH, "speed": "1.31 mm/s"}))
    assert runner.run() is RunState.REFUSED
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
    from gelrig.protocols.rig import CompressionLimits

    rig, _, _ = compression_rig(limits=CompressionLimits(max_force=0.05))
    report = rehearse(rig, protocol("compression", SEARCH, HOLD))
    assert report.state is RunState.ABORTED
    assert [h.index for h in report.hits] == [1]
    assert "force" in report.hits[0].what
    assert report.failure().startswith("step 1 (hold) at ")


def _peak_of_rehearsal(hold: str, rate: str) -> tuple[int, object]:
    import tracemalloc

    rig, _stage, _ = compression_rig()
    tracemalloc.start()
    try:
        report = rehearse(rig, protocol("compression", SEARCH,
                                        {**HOLD, "hold": hold, "rate": rate}))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert report.ok, report.reason
    return peak, report


def test_a_rehearsal_counts_the_hold_without_keeping_it() -> None:
    """Memory does not grow with the hold (issue 32): a hold 50x longer peaks within 1 MB of
    the short one, far below the 16 MB its five columns would take if kept."""
    short, _ = _peak_of_rehearsal("8 s", "1000 Hz")
    long, report = _peak_of_rehearsal("400 s", "1000 Hz")
    hold = report.steps[1]  # type: ignore[attr-defined]
    assert hold.samples > 400_000
    assert long - short < 1_000_000, (short, long)
    assert long < hold.samples * 8 * len(hold.columns) / 10


def test_a_rehearsed_hold_reports_its_samples_and_held_overlap() -> None:
    from gelrig.protocols.events import StepFinished

    rig, _stage, _ = compression_rig()
    bus = EventBus()
    finished: list[StepFinished] = []
    bus.subscribe(lambda e: finished.append(e) if isinstance(e, StepFinished) else None)
    report = rehearse(rig, protocol("compression", SEARCH, HOLD), bus)
    assert report.ok, report.reason
    result = finished[-1].results
    assert 20 * 100 < result["samples"] < report.steps[1].samples  # ramp + hold, no retract
    assert result["measured_depth_m"] == pytest.approx(0.06 * 18.63e-3, rel=0.01)
    # a rehearsal fits a thinned copy of the twin's record: what a script reading fits gets
    # (the run's fields, and a note saying where they come from)
    assert [sorted(set(f) - {"rehearsal"}) for f in result["fits"]] == [
        sorted(k for k in result["fits"][0] if k != "rehearsal")]
    assert result["fits"][0]["G_e"] > 0 and "every" in result["fits"][0]["rehearsal"]


@pytest.mark.parametrize(("hold", "rate", "expected"), [
    ("604800 s", "20000 Hz", "samples per run 12,09"),  # 7 days at 20 kHz
])
def test_a_protocol_beyond_the_run_bounds_is_refused_before_anything_moves(
        hold: str, rate: str, expected: str) -> None:
    rig, stage, _ = compression_rig()
    report = rehearse(rig, protocol("compression", SEARCH, {**HOLD, "hold": hold,
                                                             "rate": rate}))
    assert not report.ok
    assert expected in report.failure()
    assert "at most 1,000,000,000" in report.failure()
    assert stage.calls == []


def test_a_script_beyond_the_bounds_is_refused_at_the_step_that_crosses_them(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from gelrig.protocols import runner as runner_module
    from gelrig.protocols.script import Run
    from gelrig.protocols.script import protocol as script

    @script(rig="compression", name="endless")
    def endless(run: Run) -> None:
        for _ in range(10):
            run.step("ramp_hold", diameter="18.63 mm", first_touch="6.2 mm", hold="1 s",
                     rate="100 Hz", terms=1,
                     strain_rate="0.02 /s")

    monkeypatch.setattr(runner_module, "MAX_STEPS", 3)
    rig, _stage, _ = compression_rig()
    report = rehearse(rig, endless)
    assert not report.ok
    assert report.failure().startswith("step 3 (ramp and hold): step 4 of the run; at most 3 "
                                       "steps per run")
    assert [s.status for s in report.steps] == ["completed"] * 3 + ["refused"]

    @script(rig="compression", name="long")
    def long(run: Run) -> None:
        for hold in ("1 s", "604800 s"):
            run.step("ramp_hold", diameter="18.63 mm", first_touch="6.2 mm", hold=hold,
                     rate="20000 Hz", terms=1,
                     strain_rate="0.02 /s")

    rig, _stage, _ = compression_rig()
    report = rehearse(rig, long)
    assert report.failure().startswith("step 1 (ramp and hold): samples per run 12,09")
    assert [s.status for s in report.steps] == ["completed", "refused"]


def test_protocol_files_beyond_the_step_and_speed_bounds_are_refused_on_load() -> None:
    from gelrig.instrument.core.errors import ConfigError

    with pytest.raises(ConfigError, match=r'\[\[step\]\] = "1,001 tables": at most 1000 steps'):
        protocol("compression", *[HOLD] * 1001)
    ladder = {"kind": "speed_ladder", "touch_gap": "3 mm", "centre_angle": 0.8,
              "speeds": [1e-4] * 101}
    with pytest.raises(ConfigError, match=r'speeds = "101 values": at most 100 values'):
        protocol("shear", ladder)
