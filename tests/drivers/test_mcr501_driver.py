"""The MCR 501 driver against the simulator, through pyvisa-py over TCP, in virtual time.

"In-process": the simulator's TCP server runs in a thread of this process and shares the
test's VirtualClock with the driver; pyvisa-py connects to TCPIP0::127.0.0.1::PORT::SOCKET.
"""

from __future__ import annotations

import itertools
import math
import os
from typing import Any

import pytest

from gelrig.drivers.mcr501 import MCR501, VisaTransport
from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.contracts.rheometer import Rheometer, RheometerConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import DeviceErrorReply, LimitError
from gelrig.instrument.physics.sliding import rpm_from_speed
from gelrig.simulators.mcr501 import DirectLink, MCR501Simulator, SimConfig
from tests.drivers.mcr501_harness import rig

PAPER_SPEEDS = (2.38e-5, 4.75e-5, 1.19e-4, 2.37e-4)


def test_driver_meets_the_rheometer_protocol(rm: Any) -> None:
    with rig(rm) as r:
        assert isinstance(r.drv, Rheometer)


def test_identify_through_pyvisa_py(rm: Any) -> None:
    with rig(rm, SimConfig(identity=("MCR501", "SN123", "03.40"))) as r:
        ident = r.drv.identify()
        assert (ident.vendor, ident.model, ident.serial, ident.firmware) == (
            "Anton Paar", "MCR501", "SN123", "03.40")
        assert ident.extra["identity"] == "MCR501 SN123 firmware 03.40"
        assert isinstance(r.drv._transport, VisaTransport)
        assert type(r.drv._transport.resource).__name__ == "TCPIPSocket"


def test_gap_moves_need_referencing_then_take_virtual_time(rm: Any) -> None:
    with rig(rm, SimConfig(start_gap=10e-3, lift_speed=1e-3)) as r:
        with pytest.raises(DeviceErrorReply) as err:
            r.drv.set_gap(8e-3)
        assert err.value.code == 12
        assert not r.drv.status().gap_referenced
        r.drv.zero_gap()
        assert r.drv.status().gap_referenced
        t0 = r.clock.now()
        r.drv.set_gap(7.5e-3)
        assert r.drv.gap() == pytest.approx(7.5e-3, abs=1e-7)
        # 2.5 mm at 1 mm/s, to within one status poll
        assert r.clock.now() - t0 == pytest.approx(2.5, abs=r.drv.config.poll_interval + 1e-9)
        r.drv.set_gap(7.6e-3, wait=False)
        assert r.drv.status().gap_moving
        r.clock.sleep(0.05)
        assert r.drv.gap() == pytest.approx(7.55e-3, abs=1e-7)


@pytest.mark.parametrize("speed", PAPER_SPEEDS)
def test_rotation_both_directions_at_the_paper_speeds(rm: Any, speed: float) -> None:
    with rig(rm) as r:
        arm = r.drv.config.arm
        for sign in (1.0, -1.0):
            r.drv.rotate(sign * speed)
            omega = r.sim.cell.spin.target
            # the wire carries rpm = v / (2 pi L) * 60 (docs/decisions/0021)
            assert abs(omega) * 60 / (2 * math.pi) == pytest.approx(
                rpm_from_speed(speed, arm), rel=1e-6
            )
            assert r.drv.status().mode == "rotating"
            r.turn(1.0)  # past the ramp
            a0, t0 = r.drv.angle(), r.clock.now()
            r.turn(10.0)
            rate = (r.drv.angle() - a0) / (r.clock.now() - t0)
            assert rate * arm == pytest.approx(sign * speed, rel=1e-5)
            theta = r.drv.theta()
            assert theta == pytest.approx(r.drv.angle() * arm)
            r.drv.stop()
            assert not r.drv.maybe_rotating
            r.clock.sleep(1.0)
            a1 = r.drv.angle()
            r.clock.sleep(5.0)
            assert r.drv.angle() == a1
            status = r.drv.status()
            assert status.mode == "idle" and not status.busy


def test_finite_acceleration_shows_in_the_angle(rm: Any) -> None:
    with rig(rm, SimConfig(acceleration=0.5)) as r:
        speed = 4e-3
        omega = speed / r.drv.config.arm
        a0 = r.drv.angle()
        r.drv.rotate(speed)
        r.clock.sleep(0.1)
        assert r.drv.status().accelerating
        assert r.drv.angle() - a0 == pytest.approx(0.5 * 0.5 * 0.1**2, rel=1e-4)
        r.clock.sleep(1.0)
        ramp = omega / 0.5
        expected = 0.5 * 0.5 * ramp**2 + omega * (1.1 - ramp)
        assert r.drv.angle() - a0 == pytest.approx(expected, rel=1e-4)
        assert not r.drv.status().accelerating


def test_hold_keeps_the_position(rm: Any) -> None:
    with rig(rm) as r:
        r.drv.rotate(-2e-3)
        r.clock.sleep(2.0)
        r.drv.hold()
        r.clock.sleep(1.0)
        status = r.drv.status()
        assert status.mode == "holding"
        a = r.drv.angle()
        r.clock.sleep(100.0)
        assert r.drv.angle() == a
        assert r.drv.torque() == pytest.approx(0.0, abs=1e-6)  # no contact, no drag at rest


def test_measurement_stream_in_virtual_time(rm: Any) -> None:
    with rig(rm) as r:
        r.clock.sleep(3.0)
        t_start = r.clock.now()
        r.drv.start_stream(0.1)
        r.drv.rotate(1e-3)
        r.turn(25.0)  # 250 points, more than one #DATA batch
        points = r.drv.read_stream()
        assert len(points) == 250
        times = [p.t for p in points]
        assert times[0] == pytest.approx(t_start + 0.1)
        assert times[-1] == pytest.approx(t_start + 25.0)
        assert all(b - a == pytest.approx(0.1) for a, b in itertools.pairwise(times))
        arm = r.drv.config.arm
        assert all(p.theta == pytest.approx(p.angle * arm) for p in points)
        assert all(p.gap == pytest.approx(10e-3) for p in points)
        # the arm turns at 1 mm/s at the end
        v = (points[-1].theta - points[-11].theta) / (points[-1].t - points[-11].t)
        assert v == pytest.approx(1e-3, rel=1e-4)
        assert r.drv.read_stream() == []
        r.clock.sleep(0.35)
        assert len(r.drv.read_stream()) == 3
        assert r.drv.status().streaming
        r.drv.stop_stream()
        assert not r.drv.status().streaming
        r.clock.sleep(1.0)
        assert r.drv.read_stream() == []


def _stream_with_polling(poll: float | None) -> list[tuple[float, ...]]:
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True, seed=7))
    drv = MCR501(DirectLink(sim), clock).open()
    drv.set_gap(sim.config.touch_gap - 0.5e-3)
    drv.start_stream(0.2)
    drv.rotate(4e-3)
    out = []
    t_end = clock.now() + 12.0
    while clock.now() < t_end:
        step = t_end - clock.now() if poll is None else min(poll, t_end - clock.now())
        # the rotation is renewed either way (ADR 0201); only the reads differ
        keep_moving(clock, drv, step, drv.config.motion_bound)
        if poll is not None:
            drv.torque()
            out += drv.read_stream()
    out += drv.read_stream()
    drv.close()
    return [(p.t, p.angle, p.torque, p.normal_force) for p in out]


def test_stream_does_not_depend_on_how_often_the_client_polls() -> None:
    rare = _stream_with_polling(None)
    often = _stream_with_polling(0.037)
    assert len(rare) == len(often) == 60
    assert max(abs(p[3]) for p in rare) > 0.01  # the pass went through contact
    assert rare == often


def test_requests_outside_the_limits_are_not_sent(rm: Any) -> None:
    config = RheometerConfig(max_speed=2e-3, gap_max=0.02)
    with rig(rm, SimConfig(start_referenced=True), config) as r:
        before = r.sim.requests
        with pytest.raises(LimitError, match="max_speed"):
            r.drv.rotate(2.5e-3)
        with pytest.raises(LimitError, match="gap"):
            r.drv.set_gap(0.03)
        with pytest.raises(LimitError):
            r.drv.set_gap(math.nan)
        with pytest.raises(LimitError):
            r.drv.start_stream(0.0)
        assert r.sim.requests == before


def test_serial_resources_open_at_38400_8n1_xon_xoff(rm: Any) -> None:
    from pyvisa import constants

    master, slave = os.openpty()
    try:
        transport = VisaTransport(f"ASRL{os.ttyname(slave)}::INSTR", resource_manager=rm)
        try:
            res = transport.resource
            assert res.baud_rate == 38400
            assert res.data_bits == 8
            assert res.parity == constants.Parity.none
            assert res.stop_bits == constants.StopBits.one
            assert res.flow_control == constants.ControlFlow.xon_xoff
            transport.write_line("#VERS[?]")
            assert os.read(master, 64) == b"#VERS[?]\r\n"
            os.write(master, b"#VERS[MCR501;SN1;03.40]\r\n")
            assert transport.read_line() == "#VERS[MCR501;SN1;03.40]"
        finally:
            transport.close()
    finally:
        os.close(master)
        os.close(slave)
