"""The simulated KDC101 survives any bytes: random streams, valid frames with corrupted
lengths, ids and addresses, and well-formed requests with random payloads are dropped or
obeyed, never raised out of the server loop, and the controller answers a valid request
afterwards. Then the 6-byte header-only MOT_SET_ENCCOUNTER of issue 32 against a served
``gelrig sim serve kdc101 --tcp`` process, which must stay up and answer."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gelrig.drivers.kdc101 import payloads as pl
from gelrig.drivers.kdc101.apt import (
    CONTROLLER,
    FORMS,
    HOST,
    AptFramer,
    Message,
    MsgId,
    command,
    encode,
)
from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.kdc101 import KDC101Simulator
from gelrig.simulators.kdc101 import device as kdc
from gelrig.simulators.kdc101 import messages as sm

#: Every id the simulator handles, with the payload lengths it takes (() header only).
SHAPES: dict[int, tuple[int, ...]] = {
    **{i: () if f.data_len is None else (f.data_len,) for i, f in FORMS.items()
       if i in kdc._HANDLERS},
    **kdc._SIM_SHAPES,
}
HANDLED = sorted(kdc._HANDLERS)
INFO = encode(command(MsgId.HW_REQ_INFO))
ENCCOUNTER_HEADER_ONLY = bytes.fromhex("0904d4a15001")


@st.composite
def requests(draw: st.DrawFn) -> bytes:
    """A well-formed request of a handled id: random params, a payload of a length it takes
    (its channel word usually 1), or a header when it takes one."""
    msg_id = draw(st.sampled_from(HANDLED))
    lengths = SHAPES.get(msg_id, ())
    short = msg_id in (MsgId.MOT_MOVE_ABSOLUTE, MsgId.MOT_MOVE_RELATIVE)  # header too
    if not lengths or (short and draw(st.booleans())):
        p1 = draw(st.one_of(st.just(1), st.integers(0, 255)))
        return encode(command(msg_id, p1, draw(st.integers(0, 255))))
    n = draw(st.sampled_from(lengths))
    data = bytearray(draw(st.binary(min_size=n, max_size=n)))
    if n >= 2 and draw(st.integers(0, 3)):
        data[:2] = b"\x01\x00"
    return encode(Message(msg_id, 0, 0, bytes(data), CONTROLLER, HOST))


@st.composite
def corrupted(draw: st.DrawFn) -> bytes:
    """A request with one thing wrong: its length word, its id, its addresses, cut short or
    extended, or a data flag on a header-only form."""
    frame = bytearray(draw(requests()))
    how = draw(st.sampled_from(["length", "id", "dest", "source", "cut", "extend", "flag"]))
    if how == "length":
        frame[2:4] = draw(st.integers(0, 0xFFFF)).to_bytes(2, "little")
        frame[4] |= 0x80
    elif how == "id":
        frame[0:2] = draw(st.integers(0, 0xFFFF)).to_bytes(2, "little")
    elif how == "dest":
        frame[4] = draw(st.integers(0, 255))
    elif how == "source":
        frame[5] = draw(st.integers(0, 255))
    elif how == "cut":
        del frame[draw(st.integers(0, len(frame) - 1)):]
    elif how == "extend":
        frame += draw(st.binary(min_size=1, max_size=40))
    else:
        frame[4] ^= 0x80
    return bytes(frame)


chunks = st.lists(st.one_of(st.binary(max_size=64), requests(), corrupted(),
                            st.just(ENCCOUNTER_HEADER_ONLY)), max_size=25)


class FakeWall:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def answers_info(sim: KDC101Simulator, clock: VirtualClock, wall: FakeWall) -> bool:
    """After a pause longer than the inter-byte timeout, HW_REQ_INFO gets HW_GET_INFO."""
    wall.now += kdc.FRAME_GAP_S + 0.1
    sim.discard_output()
    sim.receive(INFO)
    clock.sleep(0.01)
    framer = AptFramer()
    framer.feed(sim.read())
    replies = []
    while True:
        try:
            msg = framer.next_message()
        except Exception:
            continue
        if msg is None:
            break
        replies.append(msg)
    infos = [m for m in replies if m.msg_id == MsgId.HW_GET_INFO]
    return bool(infos) and pl.HwInfo.unpack(infos[-1].data or b"").serial_number == \
        sim.config.serial_number


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(stream=chunks, pauses=st.lists(st.floats(0.0, 2.0), min_size=25, max_size=25))
def test_any_bytes_are_dropped_or_obeyed_and_the_controller_still_answers(
        stream: list[bytes], pauses: list[float]) -> None:
    clock = VirtualClock()
    sim = KDC101Simulator(clock)
    wall = FakeWall()
    sim.wall = wall
    for chunk, pause in zip(stream, pauses, strict=False):
        sim.receive(chunk)  # what the server loop does: nothing may raise out of it
        clock.sleep(pause)  # spontaneous messages (updates, move ends) come due
        wall.now += 0.001
        sim.read()
    # no handler failed on a payload: every malformed message met an explicit check
    assert not [why for _, why in sim.rejected if why.startswith("malformed")], sim.rejected
    assert answers_info(sim, clock, wall)


def test_the_header_only_enccounter_is_logged_and_dropped(
        caplog: pytest.LogCaptureFixture) -> None:
    clock = VirtualClock()
    sim = KDC101Simulator(clock)
    sim.receive(ENCCOUNTER_HEADER_ONLY)
    assert sim.rejected[-1][1] == ("MOT_SET_ENCCOUNTER: a header only, expected 6 data "
                                   "bytes")
    assert "MOT_SET_ENCCOUNTER: a header only" in caplog.text
    assert answers_info(sim, clock, FakeWall())


def test_a_partial_frame_is_dropped_after_the_inter_byte_timeout() -> None:
    clock, wall = VirtualClock(), FakeWall()
    sim = KDC101Simulator(clock)
    sim.wall = wall
    head = encode(Message(sm.SimMsgId.MOT_SET_JOGPARAMS, 0, 0, bytes(22), CONTROLLER,
                          HOST))[:10]
    sim.receive(head)  # the head of a 28-byte frame: it would swallow the next request
    wall.now += kdc.FRAME_GAP_S / 2
    sim.receive(b"")
    assert sim.stale_dropped == 0  # within the gap: kept
    assert answers_info(sim, clock, wall)
    assert sim.stale_dropped == 10


# ---- a served simulator ----------------------------------------------------------------
@pytest.fixture
def served() -> Iterator[tuple[subprocess.Popen[str], int]]:
    proc = subprocess.Popen([sys.executable, "-m", "gelrig.cli", "sim", "serve", "kdc101",
                             "--tcp", "127.0.0.1:0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        found = re.search(r"socket://127\.0\.0\.1:(\d+)", line)
        assert found, line
        yield proc, int(found[1])
    finally:
        proc.terminate()
        proc.communicate(timeout=10)  # waits, and closes the pipes


def read_reply(conn: socket.socket, msg_id: int, timeout: float = 5.0) -> Message:
    framer, deadline = AptFramer(), time.monotonic() + timeout
    while time.monotonic() < deadline:
        conn.settimeout(max(0.01, deadline - time.monotonic()))
        try:
            data = conn.recv(4096)
        except TimeoutError:
            break
        if not data:
            break
        framer.feed(data)
        while (msg := framer.next_message()) is not None:
            if msg.msg_id == msg_id:
                return msg
    raise AssertionError(f"no 0x{msg_id:04X} within {timeout} s")


def test_a_served_kdc101_survives_the_six_byte_message(
        served: tuple[subprocess.Popen[str], int]) -> None:
    proc, port = served
    with socket.create_connection(("127.0.0.1", port), timeout=5) as conn:
        conn.sendall(ENCCOUNTER_HEADER_ONLY)
        time.sleep(0.3)
        conn.sendall(INFO)
        info = pl.HwInfo.unpack(read_reply(conn, MsgId.HW_GET_INFO).data or b"")
        assert info.serial_number == 27000001
    assert proc.poll() is None  # still serving
    time.sleep(0.3)  # one client at a time: let the server see the first one go
    with socket.create_connection(("127.0.0.1", port), timeout=5) as conn:  # and again
        conn.sendall(encode(command(MsgId.MOT_REQ_POSCOUNTER, 1)))
        assert read_reply(conn, MsgId.MOT_GET_POSCOUNTER).data is not None
    assert proc.poll() is None
