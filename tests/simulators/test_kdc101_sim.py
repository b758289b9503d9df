"""The simulated KDC101 + Z825B on its own: kinematics as a pure function of time, encoder
quantization, limits, status updates and the keep-alive rule, info and error replies, spoken
as raw APT bytes over the in-process pyserial URL and through ``gelrig sim serve kdc101``."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import serial

from gelrig.drivers.kdc101 import KDC101
from gelrig.drivers.kdc101 import payloads as pl
from gelrig.drivers.kdc101.apt import AptFramer, Message, MsgId, command, data_message, encode
from gelrig.instrument.core.clock import PacedClock, VirtualClock
from gelrig.instrument.core.motion import (
    Trajectory,
    clip_to_travel,
    plan_move,
    trapezoid_duration,
)
from gelrig.simulators.kdc101 import KDC101Simulator, SimConfig, register, unregister

CPM = 34554.96
D = pl.Directions.named("forward_is_negative")  # the default convention (ADR 0100)
UP = D.code(+1)  # the direction code towards larger counts (2 on a KDC101)
ROOT = Path(__file__).resolve().parents[2]
_names = itertools.count()


# ---- kinematics --------------------------------------------------------------------------
def test_trapezoid_positions_and_duration() -> None:
    v, a = 2e-3, 4e-3  # ramps of 0.5 s over 0.5 mm
    phases = plan_move(10.0, 1e-3, 0.0, 6e-3, v, a)
    traj = Trajectory(1e-3, 0.0)
    traj.replace_from(10.0, phases)
    end = 10.0 + 5e-3 / v + v / a
    assert traj.end_time == pytest.approx(end)
    assert traj.position_at(10.25) == pytest.approx(1e-3 + 0.5 * a * 0.25**2)
    assert traj.position_at(10.5) == pytest.approx(1.5e-3)
    assert traj.velocity_at(11.0) == pytest.approx(v)
    assert traj.position_at(end - 0.5) == pytest.approx(5.5e-3)
    assert traj.position_at(end) == pytest.approx(6e-3)
    assert traj.position_at(end + 100) == 6e-3
    assert traj.position_at(5.0) == 1e-3


def test_triangle_when_the_move_is_short() -> None:
    traj = Trajectory(0.0)
    traj.replace_from(0.0, plan_move(0.0, 0.0, 0.0, 0.1e-3, 2.3e-3, 4e-3))
    assert traj.end_time == pytest.approx(2 * (0.1e-3 / 4e-3) ** 0.5)
    assert max(traj.velocity_at(t / 100 * traj.end_time) for t in range(101)) < 2.3e-3


def test_retargeting_mid_move_keeps_the_past() -> None:
    traj = Trajectory(0.0)
    traj.replace_from(0.0, plan_move(0.0, 0.0, 0.0, 10e-3, 2e-3, 4e-3))
    past = [traj.position_at(t / 10) for t in range(0, 21)]
    x, v = traj.position_at(2.0), traj.velocity_at(2.0)
    traj.replace_from(2.0, plan_move(2.0, x, v, 1e-3, 2e-3, 4e-3))  # turn round
    assert [traj.position_at(t / 10) for t in range(0, 21)] == past  # a pure function of t
    assert traj.velocity_at(2.0) == pytest.approx(v)  # no jump in velocity
    assert traj.position_at(traj.end_time) == pytest.approx(1e-3)


def test_a_trajectory_keeps_a_day_of_its_past_not_all_of_it() -> None:
    """A simulator that runs for weeks (a session of many runs) keeps a bounded path: the
    phases of the last HISTORY seconds, every position in them unchanged."""
    from gelrig.instrument.core.motion import HISTORY

    traj = Trajectory(0.0)
    t, x = 0.0, 0.0
    for k in range(3000):  # a move every 100 s for 3.5 days
        target = 5e-3 if k % 2 == 0 else 1e-3
        traj.replace_from(t, plan_move(t, x, 0.0, target, 2e-3, 4e-3))
        t, x = t + 100.0, target
    recent = [traj.position_at(t - s) for s in np.linspace(0, HISTORY - 200, 50)]
    assert len(traj._phases) <= 5 * (HISTORY / 100 + 2)  # a day of moves, not 3.5 days'
    traj.replace_from(t, plan_move(t, x, 0.0, 2e-3, 2e-3, 4e-3))
    assert [traj.position_at(t - s) for s in np.linspace(0, HISTORY - 200, 50)] == recent


def test_travel_limit_is_a_dead_stop() -> None:
    phases, t_hit = clip_to_travel(plan_move(0.0, 24e-3, 0.0, 30e-3, 2e-3, 4e-3), 0.0, 25e-3)
    assert t_hit is not None
    assert phases[-1].x0 == 25e-3 and phases[-1].v0 == 0.0
    _, none = clip_to_travel(plan_move(0.0, 1e-3, 0.0, 0.0, 2e-3, 4e-3), 0.0, 25e-3)
    assert none is None  # ending exactly on the switch is not a crash into it


# ---- raw APT over kdc101sim:// ------------------------------------------------------------
@dataclass
class Wire:
    clock: VirtualClock
    sim: KDC101Simulator
    port: serial.SerialBase
    framer: AptFramer

    def send(self, msg: Message) -> None:
        self.port.write(encode(msg))

    def messages(self, timeout: float) -> list[Message]:
        """Everything the controller says within ``timeout`` (virtual) seconds."""
        end = self.clock.now() + timeout
        out: list[Message] = []
        while self.clock.now() < end:
            self.port.timeout = end - self.clock.now()
            self.framer.feed(self.port.read(4096))
            while (m := self.framer.next_message()) is not None:
                out.append(m)
        return out

    def ask(self, msg: Message) -> Message:
        self.send(msg)
        return self.messages(0.01)[-1]


@pytest.fixture
def wire() -> Iterator[Wire]:
    clock = VirtualClock()
    sim = KDC101Simulator(clock)
    name = f"wire{next(_names)}"
    port = serial.serial_for_url(register(sim, name), timeout=0)
    yield Wire(clock, sim, port, AptFramer())
    port.close()
    unregister(name)


def test_the_simulator_keeps_only_its_latest_messages(wire: Wire,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    from gelrig.simulators.kdc101 import device

    monkeypatch.setattr(device, "KEPT_MESSAGES", 10)
    for _ in range(100):
        wire.send(command(MsgId.MOT_REQ_POSCOUNTER, 1))
    assert 10 <= len(wire.sim.received) <= 20
    assert all(m.msg_id == MsgId.MOT_REQ_POSCOUNTER for m in wire.sim.received)


def test_hw_get_info_says_kdc101_with_a_27_serial(wire: Wire) -> None:
    reply = wire.ask(command(MsgId.HW_REQ_INFO))
    info = pl.HwInfo.unpack(reply.data or b"")
    assert reply.msg_id == MsgId.HW_GET_INFO and (reply.dest, reply.source) == (0x01, 0x50)
    assert info.model == "KDC101" and str(info.serial_number)[:2] == "27"
    assert info.n_channels == 1 and info.stage_id == 9


def test_serial_numbers_must_start_with_27() -> None:
    with pytest.raises(ValueError, match="27xxxxxx"):
        SimConfig(serial_number=83000001)


def test_read_with_nothing_due_returns_after_the_timeout_in_virtual_time(wire: Wire) -> None:
    wire.port.timeout = 30.0
    t0 = wire.clock.now()
    assert wire.port.read(1) == b""
    assert wire.clock.now() - t0 == 30.0


def test_read_jumps_to_the_move_completed_message(wire: Wire) -> None:
    wire.send(data_message(MsgId.MOT_MOVE_RELATIVE, pl.pack_position(round(2 * CPM))))
    wire.port.timeout = 60.0
    t0 = wire.clock.now()
    wire.framer.feed(wire.port.read(20))  # blocks (in virtual time) until the move ends
    msg = wire.framer.next_message()
    assert msg is not None and msg.msg_id == MsgId.MOT_MOVE_COMPLETED
    took = wire.clock.now() - t0
    assert took == pytest.approx(trapezoid_duration(round(2 * CPM) / CPM * 1e-3, 2e-3, 1.5e-3))
    status = pl.DcStatus.unpack(msg.data or b"")
    assert status.position == round(2 * CPM)
    assert not status.bits & pl.BUSY


def test_encoder_counts_are_quantized(wire: Wire) -> None:
    wire.send(data_message(MsgId.MOT_MOVE_RELATIVE, pl.pack_position(1000)))
    wire.clock.advance(0.05)  # mid-move
    t = wire.clock.now()
    reply = wire.ask(command(MsgId.MOT_REQ_POSCOUNTER, 1))
    counts = pl.unpack_position(reply.data or b"")[1]
    exact = (wire.sim.position_at(t) - wire.sim.counter_origin_m) * CPM * 1e3
    assert counts == round(exact) and counts != exact
    assert 0 < counts < 1000


def test_status_updates_stop_after_50_unacknowledged(wire: Wire) -> None:
    wire.send(command(MsgId.HW_START_UPDATEMSGS))
    msgs = wire.messages(10.0)
    updates = [m for m in msgs if m.msg_id == MsgId.MOT_GET_DCSTATUSUPDATE]
    assert len(updates) == 50  # 5 s worth, then silence


def test_acknowledged_status_updates_keep_coming_every_100_ms(wire: Wire) -> None:
    wire.send(command(MsgId.HW_START_UPDATEMSGS))
    wire.send(command(MsgId.MOT_MOVE_VELOCITY, 1, UP))
    updates: list[pl.DcStatus] = []
    times: list[float] = []
    for _ in range(20):  # 10 s, acknowledging every 0.5 s
        for m in wire.messages(0.5):
            if m.msg_id == MsgId.MOT_GET_DCSTATUSUPDATE:
                updates.append(pl.DcStatus.unpack(m.data or b""))
                times.append(wire.clock.now())
        wire.send(command(MsgId.MOT_ACK_DCSTATUSUPDATE))
    assert len(updates) == 100
    assert UP == pl.DIRECTION_REVERSE
    assert all(u.bits & D.moving_bit(+1) == pl.MOVING_REVERSE for u in updates)
    positions = [u.position for u in updates]
    assert positions == sorted(positions) and positions[-1] > positions[0]


def test_velocity_move_ends_on_the_far_hard_limit(wire: Wire) -> None:
    wire.send(command(MsgId.MOT_MOVE_VELOCITY, 1, UP))
    msgs = wire.messages(30.0)  # 20 mm at 2 mm/s takes ~10 s
    stopped = [m for m in msgs if m.msg_id == MsgId.MOT_MOVE_STOPPED]
    assert len(stopped) == 1
    bits = pl.DcStatus.unpack(stopped[0].data or b"").bits
    assert bits & pl.LIMIT_REVERSE and not bits & pl.LIMIT_FORWARD and not bits & pl.BUSY
    assert wire.sim.position_at(wire.clock.now()) == 25e-3


def test_homing_sets_the_homed_bit_and_zeroes_the_counter(wire: Wire) -> None:
    wire.send(command(MsgId.MOT_MOVE_HOME, 1))
    during = pl.unpack_statusbits(wire.ask(command(MsgId.MOT_REQ_STATUSBITS, 1)).data or b"")[1]
    # Homing runs to smaller counts: the protocol's "forward" moving bit on a KDC101.
    assert during & pl.HOMING and during & pl.MOVING_FORWARD and not during & pl.MOVING_REVERSE
    msgs = wire.messages(20.0)
    assert [m.msg_id for m in msgs] == [MsgId.MOT_MOVE_HOMED]
    bits = pl.unpack_statusbits(wire.ask(command(MsgId.MOT_REQ_STATUSBITS, 1)).data or b"")[1]
    assert bits & pl.HOMED and not bits & pl.HOMING
    assert pl.unpack_position(wire.ask(command(MsgId.MOT_REQ_POSCOUNTER, 1)).data or b"")[1] == 0


@pytest.mark.parametrize(
    ("request_msg", "text"),
    [
        (command(0x0777), "unknown message id"),
        (command(MsgId.MOT_REQ_POSCOUNTER, 2), "no channel 2"),
        (data_message(MsgId.MOT_SET_VELPARAMS, pl.VelParams(0, 1000, 10**8).pack()),
         "out of range"),
        (command(MsgId.MOT_MOVE_STOP, 1, 9), "stop mode"),
        # A reply sent as a request:
        (data_message(MsgId.HW_GET_INFO, bytes(84)), "unknown message id"),
    ],
)
def test_invalid_requests_are_logged_not_answered(wire: Wire, request_msg: Message, text: str,
                                                  caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level("WARNING", logger="gelrig.simulators.kdc101"):
        wire.send(request_msg)
        # The next query's reply is the next thing on the wire: no error message before it.
        reply = wire.ask(command(MsgId.MOT_REQ_STATUSBITS, 1))
    assert reply.msg_id == MsgId.MOT_GET_STATUSBITS
    assert wire.messages(1.0) == []
    assert len(wire.sim.rejected) == 1 and text in wire.sim.rejected[0][1]
    assert text in caplog.text


def test_moving_a_disabled_channel_is_ignored_and_logged(wire: Wire) -> None:
    wire.send(command(MsgId.MOD_SET_CHANENABLESTATE, 1, pl.CHAN_DISABLED))
    wire.send(data_message(MsgId.MOT_MOVE_ABSOLUTE, pl.pack_position(5000)))
    assert wire.messages(1.0) == []
    assert "channel disabled" in wire.sim.rejected[-1][1]
    assert wire.sim.velocity_at(wire.clock.now() + 0.5) == 0.0


def _counts(wire: Wire) -> int:
    return pl.unpack_position(wire.ask(command(MsgId.MOT_REQ_POSCOUNTER, 1)).data or b"")[1]


def test_short_form_moves_use_the_stored_parameters_and_the_next_command_survives(
        wire: Wire) -> None:
    wire.send(data_message(0x0445, pl.pack_position(3000)))  # MOVERELPARAMS
    wire.send(data_message(0x0450, pl.pack_position(-8000)))  # MOVEABSPARAMS
    # Header-only MOVE_RELATIVE and a status request in the same write.
    wire.port.write(encode(command(MsgId.MOT_MOVE_RELATIVE, 1))
                    + encode(command(MsgId.MOT_REQ_STATUSBITS, 1)))
    wire.port.flush()
    first = wire.messages(0.001)
    assert [m.msg_id for m in first] == [MsgId.MOT_GET_STATUSBITS]
    assert [m.msg_id for m in wire.messages(5.0)] == [MsgId.MOT_MOVE_COMPLETED]
    assert _counts(wire) == 3000
    wire.send(command(MsgId.MOT_MOVE_ABSOLUTE, 1))
    assert [m.msg_id for m in wire.messages(5.0)] == [MsgId.MOT_MOVE_COMPLETED]
    assert _counts(wire) == -8000
    assert wire.sim.garbage_received == 0 and wire.sim.rejected == []


@pytest.mark.parametrize(
    ("set_id", "req_id", "get_id", "payload"),
    [
        (0x0416, 0x0417, 0x0418, bytes.fromhex("0100") + bytes.fromhex("0200") +
         (1000).to_bytes(4, "little") + bytes(4) + (500).to_bytes(4, "little") +
         (200000).to_bytes(4, "little") + bytes.fromhex("0100")),
        (0x043A, 0x043B, 0x043C, pl.pack_position(1234)),
        (0x0445, 0x0446, 0x0447, pl.pack_position(-77)),
        (0x0450, 0x0451, 0x0452, pl.pack_position(4321)),
        (0x04A0, 0x04A1, 0x04A2, bytes.fromhex("0100") + bytes(range(1, 19))),
        (0x04B0, 0x04B1, 0x04B2, bytes.fromhex("0100") + bytes(range(2, 26))),
        (0x0520, 0x0521, 0x0522, bytes.fromhex("0100") + bytes(range(3, 35))),
        (0x0523, 0x0524, 0x0525, bytes.fromhex("0100") + bytes(range(4, 24))),
        (0x0526, 0x0527, 0x0528, bytes.fromhex("0100") + bytes(range(5, 43))),
    ],
)
def test_parameter_blocks_read_back_what_was_set(wire: Wire, set_id: int, req_id: int,
                                                 get_id: int, payload: bytes) -> None:
    before = wire.ask(command(req_id, 1))
    assert before.msg_id == get_id and before.data is not None
    assert len(before.data) == len(payload) and before.data != payload
    wire.send(data_message(set_id, payload))
    after = wire.ask(command(req_id, 1))
    assert (after.msg_id, after.data) == (get_id, payload)
    assert wire.sim.rejected == []


def test_short_trigger_blocks_as_pylablib_sends_them_are_padded(wire: Wire) -> None:
    wire.send(data_message(0x0523, bytes.fromhex("0100 0100 0100 0b00 0000")))
    reply = wire.ask(command(0x0524, 1))
    assert reply.data == bytes.fromhex("0100 0100 0100 0b00 0000") + bytes(12)
    wire.send(data_message(0x0523, bytes.fromhex("0100") + bytes(5)))
    assert "expected 22 or 10" in wire.sim.rejected[-1][1]


def test_encoder_counter_is_the_position_counter(wire: Wire) -> None:
    wire.send(data_message(0x0409, pl.pack_position(500)))
    assert _counts(wire) == 500
    reply = wire.ask(command(0x040A, 1))
    assert reply.msg_id == 0x040B and pl.unpack_position(reply.data or b"")[1] == 500


def test_hub_bay_used_says_stand_alone(wire: Wire) -> None:
    reply = wire.ask(command(0x0065))
    assert (reply.msg_id, reply.data, reply.param1) == (0x0066, None, 0xFF)


def test_step_jog_moves_one_step_towards_the_code_and_sets_the_jogging_bit(wire: Wire) -> None:
    step = 1500
    wire.send(data_message(0x0416, bytes.fromhex("0100 0200") + step.to_bytes(4, "little")
                           + bytes(4) + (300).to_bytes(4, "little")
                           + (100000).to_bytes(4, "little") + bytes.fromhex("0200")))
    wire.send(command(0x046A, 1, UP))
    bits = pl.unpack_statusbits(wire.ask(command(MsgId.MOT_REQ_STATUSBITS, 1)).data or b"")[1]
    assert bits & D.jogging_bit(+1) and bits & D.moving_bit(+1)
    assert [m.msg_id for m in wire.messages(5.0)] == [MsgId.MOT_MOVE_COMPLETED]
    assert _counts(wire) == step
    wire.send(command(0x046A, 1, D.code(-1)))
    wire.messages(5.0)
    assert _counts(wire) == 0


def test_rehoming_clears_homed_until_it_completes(wire: Wire) -> None:
    wire.send(command(MsgId.MOT_MOVE_HOME, 1))
    wire.messages(20.0)
    wire.send(data_message(MsgId.MOT_MOVE_ABSOLUTE, pl.pack_position(round(3 * CPM))))
    wire.messages(10.0)
    wire.send(command(MsgId.MOT_MOVE_HOME, 1))
    bits = pl.unpack_statusbits(wire.ask(command(MsgId.MOT_REQ_STATUSBITS, 1)).data or b"")[1]
    assert bits & pl.HOMING and not bits & pl.HOMED
    assert [m.msg_id for m in wire.messages(20.0)] == [MsgId.MOT_MOVE_HOMED]
    bits = pl.unpack_statusbits(wire.ask(command(MsgId.MOT_REQ_STATUSBITS, 1)).data or b"")[1]
    assert bits & pl.HOMED and not bits & pl.HOMING


def test_plate_position_is_a_pure_function_of_time() -> None:
    clock = VirtualClock()
    sim = KDC101Simulator(clock)
    url = register(sim, "pure")
    try:
        stage = KDC101(url, clock=clock).open()
        stage.home()
        t0 = clock.now()
        stage.move_to(4e-3)
        t1 = clock.now()
        samples = [sim.position_at(t0 + i * (t1 - t0) / 20) for i in range(21)]
        stage.move_to(1e-3)  # later commands do not rewrite the past
        assert [sim.position_at(t0 + i * (t1 - t0) / 20) for i in range(21)] == samples
        assert samples == sorted(samples)
        assert samples[-1] - sim.counter_origin_m == pytest.approx(4e-3, abs=1e-3 / CPM)
        # In the driver's (homed) axis, scalar and vectorised, for the DAQ simulator:
        ts = np.linspace(t0, t1, 21)
        axis = sim.axis_positions_at(ts)
        assert axis[0] == pytest.approx(0.0, abs=1e-12)
        assert axis[-1] == pytest.approx(stage.config.m_from_counts(round(4 * CPM)), abs=1e-12)
        assert axis == pytest.approx([sim.axis_position_at(t) for t in ts], abs=1e-15)
        assert axis == pytest.approx(np.array(samples) - sim.counter_origin_m, abs=1e-15)
        # Before homing ended the axis was the power-on one (counter zero at 5 mm extension).
        assert sim.axis_position_at(0.0) == 0.0
        assert sim.axis_position_at(1.0) == pytest.approx(sim.position_at(1.0) - 5e-3)
        stage.close()
    finally:
        unregister("pure")


# ---- out of process: gelrig sim serve kdc101 ---------------------------------------------
@pytest.fixture
def served(request: pytest.FixtureRequest) -> Iterator[str]:
    """Start ``gelrig sim serve kdc101`` with the given options; yield the address it prints."""
    args = [sys.executable, "-m", "gelrig.cli", "sim", "serve", "kdc101", *request.param]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert "listening on" in line, line + (proc.stderr.read() if proc.stderr else "")
        yield line.rsplit(" ", 1)[-1].strip()
    finally:
        proc.terminate()
        assert proc.wait(timeout=10) == 0
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()


@pytest.mark.parametrize("served", [["--pty", "--clock", "paced:20", "--serial", "27555555"],
                                    ["--tcp", "127.0.0.1:0", "--clock", "paced:20"]],
                         indirect=True, ids=["pty", "tcp"])
def test_served_simulator_drives_like_the_real_thing(served: str) -> None:
    clock = PacedClock(20.0)  # the driver's clock runs at the server's pace
    with KDC101(served, clock=clock) as stage:
        if served.startswith("/dev/"):
            assert not stage.rts_supported  # a pty cannot toggle RTS: tolerated
            assert stage.identify().serial == "27555555"
        stage.home()
        stage.move_to(1.5e-3)
        assert stage.position_counts() == round(1.5 * CPM)
        assert stage.status().homed


def test_serve_refuses_a_virtual_clock() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "gelrig.cli", "sim", "serve", "kdc101", "--tcp", "127.0.0.1:0",
         "--clock", "virtual"], capture_output=True, text=True, cwd=ROOT, timeout=30)
    assert proc.returncode == 2
    assert "--clock" in proc.stderr and "in-process" in proc.stderr


def test_a_served_simulator_wakes_for_its_next_status_update_at_the_pace() -> None:
    """At paced:100 the next status update is due within 1 ms of real time: the server waits
    no longer for the host's bytes (POLL_S, 2 ms of real time, would be 0.2 s of lab time:
    updates would go out in pairs). On a real clock it polls every POLL_S as before."""
    from gelrig.simulators.kdc101.serve import POLL_S, TcpServer

    for rate in (100.0, 1.0):
        clock = PacedClock(rate)
        sim = KDC101Simulator(clock)
        server = TcpServer(sim)
        try:
            sim.receive(encode(command(MsgId.HW_START_UPDATEMSGS)))
            due = (sim.next_event_time() - clock.now()) / rate
            wait = server._wait()
            assert wait <= min(POLL_S, due) + 1e-9
            if rate == 1.0:
                assert wait == POLL_S
            else:
                assert wait <= 0.1 / rate
        finally:
            server.close()
