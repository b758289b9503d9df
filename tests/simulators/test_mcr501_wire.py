"""The simulator on the wire, driven by a raw socket that sends literal bytes.

This is the independent client of design.md: the bytes below are written out by hand, not
produced by the driver's codec, so a codec bug cannot hide in both ends at once.
"""

from __future__ import annotations

import re
import socket
from collections.abc import Iterator

import pytest

from gelrig.drivers.mcr501.commands import COMMANDS
from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer


class Wire:
    """A line client over a plain socket."""

    def __init__(self, port: int):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.buf = b""

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def line(self) -> bytes:
        while b"\r\n" not in self.buf:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("closed")
            self.buf += chunk
        line, self.buf = self.buf.split(b"\r\n", 1)
        return line

    def ask(self, data: bytes) -> bytes:
        self.send(data)
        return self.line()


@pytest.fixture
def served() -> Iterator[tuple[VirtualClock, MCR501Simulator, Wire]]:
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_gap=10e-3, lower_angle=0.8))
    with SimulatorServer(sim) as server:
        wire = Wire(server.port)
        try:
            yield clock, sim, wire
        finally:
            wire.sock.close()


#: One literal request per table command, and the shape of its reply.
LITERAL = {
    "identify": (b"#VERS[?]\r\n", rb"#VERS\[MCR501;SN80000000;03\.40\]"),
    "status": (b":STAT[?]\r\n", rb":STAT\[IDLE;0000\]"),
    "zero_gap": (b":GAPZ[]\r\n", rb":GAPZ\[OK\]"),
    "set_gap": (b":GAPZ[]\r\n:GAP[9.5000]\r\n", rb":GAP\[OK\]"),
    "read_gap": (b":GAP[?]\r\n", rb":GAP\[10\.0000\]"),
    "rotate": (b":ROT[CCW;8.418000e-03]\r\n", rb":ROT\[OK\]"),
    "rotate_for": (b":ROT[CW;8.418000e-03;1.5]\r\n", rb":ROT\[OK\]"),
    "stop": (b":STOP[]\r\n", rb":STOP\[OK\]"),
    "hold": (b":HOLD[]\r\n", rb":HOLD\[OK\]"),
    "read_angle": (b":ANG[?]\r\n", rb":ANG\[0\.0000000\]"),
    "read_torque": (b":TORQ[?]\r\n", rb":TORQ\[-?0\.0000\d\d\]"),
    "read_normal_force": (b":FN[?]\r\n", rb":FN\[-?0\.0000\d\d\]"),
    "start_stream": (b":RUN[0.5]\r\n", rb":RUN\[OK\]"),
    "stop_stream": (b":END[]\r\n", rb":END\[OK\]"),
    "read_stream": (b"#DATA[?]\r\n", rb"#DATA\[0;0\]"),
}


def test_the_literal_list_covers_exactly_the_table() -> None:
    assert set(LITERAL) == set(COMMANDS)


@pytest.mark.parametrize("name", sorted(LITERAL))
def test_each_table_command_is_served(
    served: tuple[VirtualClock, MCR501Simulator, Wire], name: str
) -> None:
    _, _, wire = served
    request, reply = LITERAL[name]
    if request.count(b"\r\n") == 2:  # referencing first
        assert wire.ask(request.split(b"\r\n")[0] + b"\r\n") == b":GAPZ[OK]"
        request = request.split(b"\r\n")[1] + b"\r\n"
    assert re.fullmatch(reply, wire.ask(request)), name


def test_unknown_and_malformed_requests(served: tuple[VirtualClock, MCR501Simulator, Wire]) -> None:
    _, _, wire = served
    assert wire.ask(b":FOO[]\r\n") == b"#ERR[10;unknown command :FOO]"
    assert wire.ask(b"VERS?\r\n") == b"#ERR[10;unknown command]"
    assert wire.ask(b":ROT[LEFT;1]\r\n") == b"#ERR[11;bad argument for :ROT]"
    assert wire.ask(b":GAP[1.0000]\r\n").startswith(b"#ERR[12;gap not referenced")
    assert wire.ask(b"#VERS[\xff]\r\n") == b"#ERR[10;non-ASCII bytes]"
    too_long = b"#ERR[11;line too long, at most 256 bytes]"
    assert wire.ask(b"#VERS[?]" + b"x" * 2000 + b"\r\n") == too_long
    assert wire.ask(b"#VERS[?]\n").startswith(b"#VERS[")  # a bare LF is accepted too
    assert wire.ask(b"#VERS[?]\r").startswith(b"#VERS[")  # and a bare CR


def test_stream_records_on_the_wire(served: tuple[VirtualClock, MCR501Simulator, Wire]) -> None:
    clock, _, wire = served
    assert wire.ask(b":RUN[0.25]\r\n") == b":RUN[OK]"
    assert wire.ask(b":ROT[CW;1.000000e-01]\r\n") == b":ROT[OK]"
    clock.sleep(1.0)
    assert wire.ask(b"#DATA[?]\r\n") == b"#DATA[4;0]"
    records = [wire.line() for _ in range(4)]
    number = rb"-?\d+\.\d+"
    pattern = rb":MEAS\[(%s);(%s);(%s);(%s);(%s)\]" % ((number,) * 5)
    times = []
    for rec in records:
        m = re.fullmatch(pattern, rec)
        assert m, rec
        times.append(float(m.group(1)))
        assert float(m.group(5)) == 10.0
    assert times == [0.25, 0.5, 0.75, 1.0]
    angle = float(re.fullmatch(pattern, records[-1]).group(2))  # type: ignore[union-attr]
    # 0.1 rpm (0.010472 rad/s) reached after a 0.020944 s ramp at 0.5 rad/s^2
    assert angle == pytest.approx(0.5937168, abs=2e-7)


def test_status_flags_on_the_wire(served: tuple[VirtualClock, MCR501Simulator, Wire]) -> None:
    clock, _, wire = served
    assert wire.ask(b":GAPZ[]\r\n") == b":GAPZ[OK]"
    assert wire.ask(b":GAP[9.0000]\r\n") == b":GAP[OK]"
    assert wire.ask(b":ROT[CW;1.000000e+00]\r\n") == b":ROT[OK]"
    # lift moving 0x01, referenced 0x02, accelerating 0x08
    assert wire.ask(b":STAT[?]\r\n") == b":STAT[ROT;000B]"
    clock.sleep(2.0)
    assert wire.ask(b":STAT[?]\r\n") == b":STAT[ROT;0002]"
    assert wire.ask(b":HOLD[]\r\n") == b":HOLD[OK]"
    clock.sleep(1.0)
    assert wire.ask(b":STAT[?]\r\n") == b":STAT[HOLD;0002]"


def test_a_second_client_gets_one_error_line_and_is_closed(
    served: tuple[VirtualClock, MCR501Simulator, Wire],
) -> None:
    _, sim, wire = served
    port = int(wire.sock.getpeername()[1])
    other = Wire(port)
    try:
        other.send(b":GAPZ[]\r\n")
        assert other.line() == b"#ERR[20;instrument busy, another client is connected]"
        with pytest.raises(ConnectionError):  # closed after that one line
            other.line()
        assert other.buf == b""
        assert wire.ask(b":STAT[?]\r\n") == b":STAT[IDLE;0000]"
        assert not sim.referenced
    finally:
        other.sock.close()
