"""pylablib's KinesisMotor, an independent APT client, against the simulator (in-process URL
and the TCP server); and our Stage implemented on it. Skipped if pylablib is not installed."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest

from gelrig.instrument.contracts.stage import Stage, StageConfig
from gelrig.instrument.core.clock import PacedClock, VirtualClock
from gelrig.instrument.core.errors import DeviceErrorReply, LimitError
from gelrig.simulators.kdc101 import KDC101Simulator, register, unregister
from gelrig.simulators.kdc101.serve import TcpServer

kinesis = pytest.importorskip("pylablib.devices.Thorlabs.kinesis", exc_type=ImportError)

from gelrig.drivers.kdc101.pylablib_backend import PylablibKDC101, pylablib_conn  # noqa: E402

CPM = 34554.96
_names = itertools.count()


@dataclass
class Sim:
    clock: VirtualClock
    sim: KDC101Simulator
    url: str


@pytest.fixture
def sim() -> Iterator[Sim]:
    clock = VirtualClock()
    s = KDC101Simulator(clock)
    name = f"pll{next(_names)}"
    yield Sim(clock, s, register(s, name))
    unregister(name)


def _motor(address: str, scale: Any = "step") -> Any:
    return kinesis.KinesisMotor(pylablib_conn(address), scale=scale)


def test_kinesis_motor_reads_info_and_moves_in_process(sim: Sim) -> None:
    motor = _motor(sim.url)
    try:
        info = motor.get_device_info()
        assert info.model_no == "KDC101" and str(info.serial_no).startswith("27")
        assert info.nchannels == 1 and info.fw_ver == "3.0.10"
        assert motor.get_position() == 0
        assert "enabled" in motor.get_status()
        motor.move_by(1000)
        assert motor.is_moving()
        sim.clock.advance(5.0)
        assert motor.get_position() == 1000
        assert not motor.is_moving()
        motor.move_to(-2 * round(CPM))
        sim.clock.advance(5.0)
        assert motor.get_position() == -2 * round(CPM)
        motor.home(sync=False)
        sim.clock.advance(20.0)
        assert motor.is_homed() and motor.get_position() == 0
    finally:
        motor.close()


def test_kinesis_motor_recognises_the_z825_and_its_scale(sim: Sim) -> None:
    motor = _motor(sim.url, scale="stage")
    try:
        assert motor.get_stage() == "Z825"
        # pylablib's Z8 scale is the 34304 counts/mm of the manual's example (ADR 0003).
        assert motor.get_scale()[0] == pytest.approx(34304e3)
        vp = motor.get_velocity_parameters(scale=False)
        assert vp.max_velocity == round(2.0e-3 * CPM * 1e3 * 2048 / 6e6 * 65536)
    finally:
        motor.close()


def test_kinesis_motor_over_the_tcp_server() -> None:
    clock = PacedClock(10.0)
    server = TcpServer(KDC101Simulator(clock)).start()
    try:
        motor = _motor(server.address)
        try:
            assert str(motor.get_device_info().serial_no).startswith("27")
            start = motor.get_position()
            motor.move_by(3000)
            motor.wait_move(timeout=5.0)  # pylablib's own (real-time) wait
            assert motor.get_position() == start + 3000
        finally:
            motor.close()
    finally:
        server.stop()


def test_stage_on_pylablib_homes_moves_and_refuses_limits(sim: Sim) -> None:
    stage = PylablibKDC101(sim.url, StageConfig(max_position_m=15e-3), sim.clock).open()
    try:
        assert isinstance(stage, Stage)
        assert stage.identity.model == "KDC101"
        stage.home()
        assert stage.status().homed and stage.position() == 0.0
        t0 = sim.clock.now()
        stage.move_to(2e-3)
        assert stage.position() == pytest.approx(2e-3, abs=1e-3 / CPM)
        assert 2e-3 / 2.3e-3 < sim.clock.now() - t0 < 2e-3 / 2.3e-3 + 1.0
        with pytest.raises(LimitError):
            stage.move_to(16e-3)
        stage.move_velocity(+1)
        sim.clock.advance(1.0)
        stage.stop()
        assert not stage.is_moving()
        assert 2.5e-3 < stage.position() < 5e-3
    finally:
        stage.close()


def test_stage_on_pylablib_maps_error_replies(sim: Sim) -> None:
    stage = PylablibKDC101(sim.url, clock=sim.clock).open()
    try:
        sim.sim.inject_error(0x0457, 4, "channel disabled")
        with pytest.raises(DeviceErrorReply):
            stage.move_velocity(+1)
            stage.status()
    finally:
        stage.close()
