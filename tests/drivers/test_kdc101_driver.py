"""HIL: our KDC101 driver against the simulated KDC101 + Z825B, through the pyserial URL
``kdc101sim://``, in virtual time."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from gelrig.drivers.kdc101 import KDC101
from gelrig.drivers.kdc101.apt import CHANNEL, MsgId, command, encode
from gelrig.drivers.kdc101.payloads import Directions
from gelrig.instrument.contracts.stage import FORWARD_IS_NEGATIVE, Stage, StageConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import LimitError
from gelrig.simulators.kdc101 import (
    KDC101Simulator,
    SimConfig,
    register,
    trapezoid_duration,
    unregister,
)

CPM = 34554.96
_names = itertools.count()


@dataclass
class Rig:
    clock: VirtualClock
    sim: KDC101Simulator
    url: str
    stage: KDC101


@pytest.fixture
def rig() -> Iterator[Rig]:
    clock = VirtualClock(100.0)
    sim = KDC101Simulator(clock)
    name = f"drv{next(_names)}"
    url = register(sim, name)
    stage = KDC101(url, StageConfig(max_position_m=20e-3), clock).open()
    yield Rig(clock, sim, url, stage)
    stage.close()
    unregister(name)


def run_for(rig: Rig, seconds: float, step: float = 0.1) -> None:
    """Let ``seconds`` of clock time pass while gelrig is alive: a call every ``step`` renews
    a segmented move, as every wait of gelrig's does (ADR 0201)."""
    end = rig.clock.now() + seconds
    while rig.clock.now() < end:
        rig.clock.sleep_until(min(rig.clock.now() + step, end))
        rig.stage.keep_alive()


def test_it_is_a_stage(rig: Rig) -> None:
    assert isinstance(rig.stage, Stage)


def test_identify_reads_the_kdc101_info(rig: Rig) -> None:
    ident = rig.stage.identify()
    assert ident.model == "KDC101"
    assert (ident.vendor, ident.serial, ident.firmware) == ("Thorlabs", "27000001", "3.0.10")
    assert ident.extra["channels"] == "1"
    assert ident.extra["serial_number"] == "27000001"  # run.json's former key


def test_open_sequence_sends_no_flash_programming_first_and_enables(rig: Rig) -> None:
    ids = [m.msg_id for m in rig.sim.received]
    assert ids[0] == 0x0018  # HW_NO_FLASH_PROGRAMMING
    assert 0x0005 in ids and 0x0210 in ids
    assert rig.stage.status().enabled


def test_velocity_parameters_reach_the_controller_in_apt_units(rig: Rig) -> None:
    rig.stage.set_velocity(1.5e-3, 2e-3)
    p = rig.stage.velocity_params()
    assert p.max_velocity == round(1.5 * 772981.3692)
    assert p.acceleration == round(2.0 * 263.8443072)
    assert p.min_velocity == 0


def test_home_zeroes_the_counter_at_the_home_offset(rig: Rig) -> None:
    assert not rig.stage.status().homed
    start = rig.clock.now()
    rig.stage.home()
    st = rig.stage.status()
    assert st.homed and not st.busy
    assert rig.stage.position_counts() == 0
    # The 0.1 mm home offset is held in whole encoder counts.
    offset = round(0.1 * CPM) / CPM * 1e-3
    assert rig.sim.position_at(rig.clock.now()) == pytest.approx(offset, abs=1e-12)
    # 5 mm to the switch at 1 mm/s then 0.1 mm back out, both trapezoids at 4 mm/s^2.
    expected = trapezoid_duration(5e-3, 1e-3, 4e-3) + trapezoid_duration(0.1e-3, 1e-3, 4e-3)
    assert rig.clock.now() - start == pytest.approx(expected, rel=1e-3)


def test_absolute_move_lands_on_the_encoder_count(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.move_to(3.25e-3)
    assert rig.stage.position_counts() == round(3.25 * CPM)
    assert rig.stage.position() == pytest.approx(3.25e-3, abs=0.5e-3 / CPM)
    assert not rig.stage.is_moving()


def test_relative_move_adds_to_the_position(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.move_to(2e-3)
    rig.stage.move_by(-0.5e-3)
    assert rig.stage.position_counts() == round(2 * CPM) + round(-0.5 * CPM)


def test_move_duration_matches_its_trapezoid(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.set_velocity(2.0e-3, 3.0e-3)
    p = rig.stage.velocity_params()
    v = p.max_velocity / 772981.3692 * 1e-3  # what the controller really runs at
    a = p.acceleration / 263.8443072 * 1e-3
    for distance in (6e-3, 0.4e-3):  # a trapezoid and a triangle
        t0 = rig.clock.now()
        x0 = rig.sim.position_at(t0)
        rig.stage.move_to(rig.stage.position() + distance)
        took = rig.clock.now() - t0
        travelled = rig.sim.position_at(rig.clock.now()) - x0  # whole counts
        assert travelled == pytest.approx(distance, abs=1e-3 / CPM)  # within one count
        assert took == pytest.approx(trapezoid_duration(travelled, v, a), abs=1e-7)
    assert trapezoid_duration(6e-3, 2e-3, 3e-3) == pytest.approx(6 / 2 + 2 / 3)


def test_non_blocking_move_reports_moving_with_direction_bits(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.move_to(10e-3, wait=False)
    rig.clock.advance(1.0)
    st = rig.stage.status()
    assert st.moving and st.busy
    assert st.raw & 0x20 and not st.raw & 0x10  # KDC101: 0x20 is towards larger counts
    assert 0 < rig.stage.position() < 10e-3
    rig.stage.wait_until_stopped()
    assert rig.stage.position_counts() == round(10 * CPM)


def test_stop_mid_move_immediate_and_profiled(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.move_to(15e-3, wait=False)
    run_for(rig, 2.0)
    where = rig.stage.position()
    rig.stage.stop(immediate=True)
    assert not rig.stage.is_moving()
    assert rig.stage.position() == pytest.approx(where, abs=1e-7)

    rig.stage.move_to(15e-3, wait=False)
    run_for(rig, 3.0)  # cruising at 2.3 mm/s
    before = rig.stage.position()
    rig.stage.stop(immediate=False)
    rig.stage.wait_until_stopped()
    coast = rig.stage.position() - before
    assert coast == pytest.approx(2.3e-3**2 / (2 * 4e-3), rel=1e-3)  # v^2 / 2a
    assert rig.stage.position() < 15e-3


def test_velocity_move_runs_until_stopped(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.move_velocity(+1)
    run_for(rig, 2.0)
    p = rig.stage.position()
    ramp = 2.3e-3 / 4e-3
    assert p == pytest.approx(2.3e-3 * (2.0 - ramp) + 0.5 * 4e-3 * ramp**2, rel=1e-4)
    rig.stage.move_velocity(-1)
    run_for(rig, 0.1)
    assert rig.stage.status().raw & 0x20  # still decelerating: 0.575 s to turn round
    run_for(rig, 1.0)
    assert rig.stage.status().raw & 0x10  # now moving towards smaller positions
    rig.stage.stop()
    assert not rig.stage.is_moving()


def test_a_velocity_move_ends_at_the_software_limit(rig: Rig) -> None:
    rig.stage.home()
    rig.stage.move_velocity(+1)
    run_for(rig, 60.0)
    st = rig.stage.status()
    assert not st.busy
    assert st.raw & 0x08  # the soft limit of larger counts (the protocol's "reverse")
    assert rig.stage.position_counts() == pytest.approx(round(20 * CPM), abs=1)


def test_hard_limit_switch_bits(rig: Rig) -> None:
    # Not homed: the controller's soft limits are inactive; a velocity move from another
    # client (gelrig's own stays within the software limits) runs into the home-end switch.
    rig.sim.receive(encode(command(MsgId.MOT_MOVE_VELOCITY, CHANNEL,
                                   Directions.named(FORWARD_IS_NEGATIVE).code(-1))))
    rig.clock.advance(10.0)
    st = rig.stage.status()
    assert st.at_lower_limit and not st.at_upper_limit and not st.busy
    assert rig.sim.position_at(rig.clock.now()) == 0.0


def test_software_limits_refuse_before_any_byte(rig: Rig) -> None:
    rig.stage.home()
    port = rig.stage._port
    sent_before = len(port.write_log)
    with pytest.raises(LimitError, match="outside the software travel limits"):
        rig.stage.move_to(20.001e-3)
    with pytest.raises(LimitError):
        rig.stage.move_to(-1e-6)
    assert len(port.write_log) == sent_before  # nothing was sent
    with pytest.raises(LimitError):
        rig.stage.move_by(25e-3)
    assert rig.stage.position_counts() == 0  # nothing moved
    with pytest.raises(LimitError):
        rig.stage.set_velocity(3e-3, 1e-3)


def test_status_updates_are_kept_alive_by_the_driver() -> None:
    clock = VirtualClock()
    sim = KDC101Simulator(clock)
    url = register(sim, "keepalive")
    try:
        stage = KDC101(url, clock=clock, status_updates=True).open()
        stage.home()  # ~5.6 s of reading: 56 updates, more than the 50 unacknowledged limit
        stage.move_to(5e-3)
        assert stage.last_status_update is not None
        assert stage.last_status_update.bits & 0x400  # homed
        assert clock.now() - stage._last_update <= 0.1 + 1e-9
        assert sim.unacked_updates < 10
        acks = [m for m in sim.received if m.msg_id == 0x0492]
        assert len(acks) >= 14  # one every 0.5 s over ~8 s
        stage.close()
    finally:
        unregister("keepalive")


def test_calibration_mismatch_is_visible_with_a_wrong_counts_per_mm() -> None:
    """ADR 0003: a rig file with 34304 against an actuator of 34554.96 counts/mm."""
    clock = VirtualClock()
    sim = KDC101Simulator(clock, SimConfig(counts_per_mm=34554.96))
    url = register(sim, "calib")
    try:
        stage = KDC101(url, StageConfig(counts_per_mm=34304.0), clock).open()
        stage.home()
        stage.move_to(10e-3)
        travelled = sim.position_at(clock.now()) - sim.counter_origin_m
        assert travelled == pytest.approx(10e-3 * 34304 / 34554.96, rel=1e-6)
        assert stage.position() == pytest.approx(10e-3, abs=1e-7)  # the driver can't tell
        stage.close()
    finally:
        unregister("calib")


def test_status_updates_are_position_reports_within_their_send_windows() -> None:
    """Every status update taken as a report was sent (by the simulator, with a 1 ms link
    latency) within its window, and holds the position of that moment; the host reads only
    every 0.32 s, yet the windows, narrowed by the stream's period, are a few ms wide."""
    from gelrig.instrument.core.stage_path import PathReport

    clock = VirtualClock()
    sim = KDC101Simulator(clock, SimConfig(reply_latency_s=1e-3))
    url = register(sim, "updates-path")
    try:
        stage = KDC101(url, StageConfig(status_updates=True), clock=clock).open()
        stage.move_to(5e-3)
        stage.move_to(7e-3, wait=False)
        end = clock.now() + 4.0
        while clock.now() < end:
            clock.sleep(0.32)  # the host is busy elsewhere (a DAQ transfer's wait)
            stage.position()
        updates = [r for r in stage.path._reports if r.source == "update"]
        assert len(updates) >= 30 and stage.status_reports == len(updates)
        cpm = stage.config.counts_per_mm * 1e3
        for r in updates:
            # the update was sent at a multiple of the period after the stream started; the
            # position it holds is the simulator's at some instant of its window
            xs = [sim.counts_at(t) / cpm for t in np.linspace(r.lo, r.hi, 50)]
            assert min(xs) - 1 / cpm <= r.x <= max(xs) + 1 / cpm, r
        widths = np.array([r.hi - r.lo for r in updates])
        assert np.median(widths) < 0.03
        assert isinstance(updates[0], PathReport)
        assert stage.path.disagreements == 0
        stage.close()
    finally:
        unregister("updates-path")
