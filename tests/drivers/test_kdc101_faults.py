"""Faults on the wire: garbage, truncated frames, unknown ids, error replies, a link that goes
quiet or vanishes mid-move. The driver must resynchronise or raise a typed error, and stop."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

from gelrig.drivers.kdc101 import KDC101
from gelrig.drivers.kdc101.apt import Message, MsgId, command, decode, encode
from gelrig.drivers.kdc101.payloads import DcStatus, pack_position
from gelrig.instrument.core.clock import PacedClock, VirtualClock
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    InstrumentError,
    InstrumentTimeout,
)
from gelrig.simulators.kdc101 import KDC101Simulator, SimConfig, register, unregister
from gelrig.simulators.kdc101.serve import TcpServer

CPM = 34554.96
_names = itertools.count()


@dataclass
class Rig:
    clock: VirtualClock
    sim: KDC101Simulator
    stage: KDC101


def _rig(config: SimConfig | None = None) -> Iterator[Rig]:
    clock = VirtualClock()
    sim = KDC101Simulator(clock, config)
    name = f"fault{next(_names)}"
    stage = KDC101(register(sim, name), clock=clock).open()
    stage.home()
    yield Rig(clock, sim, stage)
    stage.close()
    unregister(name)


@pytest.fixture
def rig() -> Iterator[Rig]:
    yield from _rig()


def _to_host(msg_id: int, data: bytes) -> bytes:
    return encode(Message(msg_id, 0, 0, data, 0x01, 0x50))


def test_garbage_before_a_reply_is_skipped(rig: Rig) -> None:
    rig.stage.move_to(2e-3)
    rig.sim.inject(b"\xde\xad\xbe\xef\x00\x01\x02garbage\xff\xff")
    assert rig.stage.position_counts() == round(2 * CPM)
    assert rig.stage.framing_errors >= 1
    assert rig.stage._framer.discarded >= 10


def test_truncated_frame_costs_one_retry_not_the_answer(rig: Rig) -> None:
    rig.stage.move_to(1e-3)
    whole = _to_host(MsgId.MOT_GET_DCSTATUSUPDATE, DcStatus(5, 0, 0, 0).pack())
    rig.sim.inject(whole[:11])  # the header promises 14 bytes; 5 came
    t0 = rig.clock.now()
    assert rig.stage.position_counts() == round(1 * CPM)
    assert rig.stage.framing_errors >= 1
    # It waited half the reply timeout for the swallowed answer, then asked again: the
    # retry fits in the one deadline (ADR 0060).
    assert rig.clock.now() - t0 == pytest.approx(rig.stage.config.reply_timeout_s / 2, abs=1e-6)


def test_unknown_message_from_the_controller_is_ignored(rig: Rig) -> None:
    rig.sim.inject(_to_host(0x7777, b"\x01\x00abc"))
    rig.sim.inject(encode(Message(0x0999, 3, 4, None, 0x01, 0x50)))
    assert rig.stage.position_counts() == 0
    assert rig.stage.ignored_messages == 2
    assert rig.stage.framing_errors == 0


def test_unknown_message_to_the_controller_is_logged_not_answered(rig: Rig) -> None:
    rig.stage._send(command(0x7777))
    assert rig.stage.position_counts() == 0  # the next reply is not shifted by an error
    assert "unknown message id 0x7777" in rig.sim.rejected[-1][1]


def test_error_reply_to_a_move_raises_and_commands_a_stop(rig: Rig) -> None:
    rig.sim.inject_error(MsgId.MOT_MOVE_ABSOLUTE, 4, "channel disabled")
    with pytest.raises(DeviceErrorReply, match="channel disabled") as info:
        rig.stage.move_to(3e-3)
    assert info.value.code == 4
    last = rig.sim.received[-1]
    assert (last.msg_id, last.param2) == (MsgId.MOT_MOVE_STOP, 1)
    assert rig.sim.position_at(rig.clock.now()) == pytest.approx(rig.sim.counter_origin_m)


def test_plain_hw_response_is_an_error_reply_too(rig: Rig) -> None:
    rig.sim.inject_error(0, 7, "", rich=False)
    with pytest.raises(DeviceErrorReply, match="HW_RESPONSE"):
        rig.stage.status()


def test_a_disabled_channel_ignores_moves_and_the_driver_reports_the_miss(rig: Rig) -> None:
    rig.stage.disable()
    with pytest.raises(InstrumentError, match="target was"):
        rig.stage.move_to(3e-3)
    assert "channel disabled" in rig.sim.rejected[-1][1]
    assert rig.sim.position_at(rig.clock.now()) == pytest.approx(rig.sim.counter_origin_m)


def test_quiet_link_mid_move_times_out_and_stops_the_stage(rig: Rig) -> None:
    rig.stage.move_to(10e-3, wait=False)
    rig.clock.advance(1.0)
    rig.sim.mute()  # replies are lost; commands still arrive
    # the first request after 1 s renews the move's segment: it asks for the position first
    with pytest.raises(InstrumentTimeout, match=r"no MOT_GET_(STATUSBITS|POSCOUNTER)"):
        rig.stage.wait_until_stopped()
    now = rig.clock.now()
    assert rig.sim.received[-1].msg_id == MsgId.MOT_MOVE_STOP
    assert rig.sim.velocity_at(now) == 0.0
    # It ran ~3 s (1 s + one reply timeout) at <= 2.3 mm/s, then stopped dead: short of 10 mm.
    assert rig.sim.position_at(now) - rig.sim.counter_origin_m < 7e-3
    assert rig.sim.position_at(now + 5.0) == rig.sim.position_at(now)


def test_disconnect_mid_move_raises_and_tries_to_stop(rig: Rig) -> None:
    rig.stage.move_to(10e-3, wait=False)
    rig.clock.advance(1.0)
    rig.sim.disconnect()
    with pytest.raises(Disconnected, match="disconnected"):
        rig.stage.wait_until_stopped()
    last_try = decode(rig.stage._port.write_log[-1])
    assert (last_try.msg_id, last_try.param2) == (MsgId.MOT_MOVE_STOP, 1)


def test_open_on_an_unknown_simulator_is_a_typed_error() -> None:
    with pytest.raises(Disconnected, match="cannot open"):
        KDC101("kdc101sim://nobody-registered", clock=VirtualClock()).open()


def test_tcp_peer_vanishing_mid_move_raises_disconnected() -> None:
    clock = PacedClock(5.0)  # reply timeout 2 s = 0.4 s real: ample for a loaded machine
    sim = KDC101Simulator(clock)
    server = TcpServer(sim).start()
    try:
        stage = KDC101(server.address, clock=clock).open()
        stage.move_by(10e-3, wait=False)
        sim.disconnect()  # the server drops the connection
        with pytest.raises(InstrumentError) as info:
            stage.wait_until_stopped()
        assert isinstance(info.value, Disconnected)
        assert sim.velocity_at(clock.now()) > 0  # (the stop could not get through)
        stage.close()
    finally:
        server.stop()


def test_garbage_on_the_host_side_does_not_upset_the_controller(rig: Rig) -> None:
    rig.stage._port.write(b"\x00\xff\x13\x37" + pack_position(5))
    assert rig.stage.position_counts() == 0
    assert rig.sim.garbage_received >= 1
