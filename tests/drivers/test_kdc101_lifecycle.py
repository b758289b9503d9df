"""The KDC101 lifecycle (ADR 0050): no I/O before open(), idempotent close, and Ctrl-C while
the stage moves sends MOT_MOVE_STOP over the wire before the KeyboardInterrupt propagates."""

from __future__ import annotations

import itertools
import logging
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
import serial

from gelrig.drivers.kdc101 import KDC101
from gelrig.drivers.kdc101.apt import MsgId, decode
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import Disconnected
from gelrig.simulators.kdc101 import KDC101Simulator, register, unregister

_names = itertools.count()


@dataclass
class Wire:
    clock: VirtualClock
    sim: KDC101Simulator
    url: str


@pytest.fixture
def wire() -> Iterator[Wire]:
    clock = VirtualClock()
    sim = KDC101Simulator(clock)
    name = f"life{next(_names)}"
    yield Wire(clock, sim, register(sim, name))
    unregister(name)


def test_constructing_does_no_io() -> None:
    stage = KDC101("kdc101sim://nobody-registered", clock=VirtualClock())
    assert not stage.is_open
    with pytest.raises(Disconnected, match="not open"):
        stage.position()
    with pytest.raises(Disconnected, match="cannot open"):
        stage.open()
    assert not stage.is_open
    stage.close()  # nothing to close: no error


def test_nothing_reaches_the_controller_until_open(wire: Wire) -> None:
    stage = KDC101(wire.url, clock=wire.clock)
    assert wire.sim.received == []
    assert stage.open() is stage
    assert stage.is_open and wire.sim.received
    assert stage.identity is not None and stage.identity.model == "KDC101"
    sent = len(wire.sim.received)
    stage.open()  # already open: a no-op
    assert len(wire.sim.received) == sent
    stage.close()
    stage.close()  # idempotent
    assert not stage.is_open


def test_an_unopened_pyserial_port_is_opened_by_open(wire: Wire) -> None:
    port = serial.serial_for_url(wire.url, do_not_open=True)
    stage = KDC101(port, clock=wire.clock)
    assert not port.is_open
    with stage:
        assert port.is_open and stage.status().enabled
    assert not port.is_open


def test_the_context_manager_opens_and_closes(wire: Wire) -> None:
    with KDC101(wire.url, clock=wire.clock) as stage:
        assert stage.is_open
        stage.home()
    assert not stage.is_open


def _interrupt_reads_while_moving(stage: KDC101, wire: Wire,
                                  monkeypatch: pytest.MonkeyPatch) -> None:
    port = stage._port
    real_read = port.read

    def read(size: int = 1) -> bytes:
        if wire.sim.velocity_at(wire.clock.now()) > 0:
            raise KeyboardInterrupt  # Ctrl-C while the driver waits for a reply
        return bytes(real_read(size))

    monkeypatch.setattr(port, "read", read)


def test_ctrl_c_during_a_move_stops_the_stage_first(wire: Wire,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    with KDC101(wire.url, clock=wire.clock) as stage:
        stage.home()
        _interrupt_reads_while_moving(stage, wire, monkeypatch)
        with pytest.raises(KeyboardInterrupt):
            stage.move_to(10e-3)
        last = wire.sim.received[-1]
        assert last.msg_id == MsgId.MOT_MOVE_STOP
        now = wire.clock.now()
        assert wire.sim.velocity_at(now + 0.5) == 0.0
        assert wire.sim.position_at(now + 0.5) - wire.sim.counter_origin_m < 9e-3
        monkeypatch.undo()
        wire.clock.advance(0.5)
        assert not stage.status().busy


def test_a_failed_stop_is_logged_and_ctrl_c_still_propagates(
    wire: Wire, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    with KDC101(wire.url, clock=wire.clock) as stage:
        stage.home()
        port = stage._port
        real_write = port.write

        def write(data: bytes) -> int | None:
            if decode(data).msg_id == MsgId.MOT_MOVE_STOP:
                raise serial.SerialException("cable pulled")  # the stop cannot get through
            return real_write(data)

        monkeypatch.setattr(port, "write", write)
        _interrupt_reads_while_moving(stage, wire, monkeypatch)
        with caplog.at_level(logging.ERROR), pytest.raises(KeyboardInterrupt) as info:
            stage.move_to(10e-3)
        failures = [r for r in caplog.records if "stop after KeyboardInterrupt failed" in
                    r.getMessage()]
        assert len(failures) == 1  # nested guards try the stop once per fault
        assert any("cable pulled" in note for note in info.value.__notes__)
        assert MsgId.MOT_MOVE_STOP not in [m.msg_id for m in wire.sim.received]
        monkeypatch.undo()
        stage.stop()
