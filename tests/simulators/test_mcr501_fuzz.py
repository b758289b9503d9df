"""The simulated MCR 501 survives any bytes: random byte streams, request lines of every
table command with random arguments (huge, tiny, negative, malformed numbers), and valid
requests cut, doubled or with their brackets broken, fed through the server's line framing
(:func:`replies_to`) are each answered (a reply or an ``#ERR``), never raised out of the
server loop, and a valid request is answered afterwards; also over TCP."""

from __future__ import annotations

import re
import socket

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gelrig.drivers.mcr501.commands import COMMANDS, ERROR
from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer
from gelrig.simulators.mcr501.lines import LineSplitter
from gelrig.simulators.mcr501.server import MAX_LINE, replies_to

ENDS = [b"\r\n", b"\r", b"\n"]
#: What a number field may be sent as: ordinary, extreme, or not a number at all.
numbers = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.sampled_from(["1e308", "1e309", "-1e400", "1e-400", "0", "-0", "+5", ".5", "5.",
                     "nan", "inf", "-inf", "1e", "--1", "0x10", "", " 1", "1;2",
                     "9" * 400]),
    st.integers(-10**30, 10**30).map(str),
)


@st.composite
def request_lines(draw: st.DrawFn) -> bytes:
    """A line of a table command: its literal form, or its fields with random values."""
    command = draw(st.sampled_from(sorted(COMMANDS.values(), key=lambda c: c.name)))
    shape = command.request.shape
    key = command.request.key
    if isinstance(shape, str):
        body = draw(st.one_of(st.just(shape), st.text(max_size=8)))
    else:
        parts = []
        for field in shape:
            if field.kind in ("number", "integer"):
                parts.append(draw(numbers))
            elif field.pattern and "|" in field.pattern:
                parts.append(draw(st.sampled_from([*re.sub(r"\\", "", field.pattern)
                                                   .split("|"), "cw", "X", ""])))
            else:
                parts.append(draw(st.text(max_size=12)))
        if draw(st.integers(0, 5)) == 0:  # one field too many or too few
            parts = parts[:-1] if parts and draw(st.booleans()) else [*parts, "1"]
        body = ";".join(parts)
    line = f"{key}[{body}]"
    mangle = draw(st.sampled_from(["none", "none", "none", "cut", "brackets", "double"]))
    if mangle == "cut":
        line = line[:draw(st.integers(0, len(line)))]
    elif mangle == "brackets":
        line = line.replace("[", draw(st.sampled_from(["[[", "", "]"])), 1)
    elif mangle == "double":
        line = line + line
    return line.encode("utf-8", "surrogatepass") + draw(st.sampled_from(ENDS))


streams = st.lists(st.one_of(st.binary(max_size=80), request_lines(),
                             st.binary(min_size=MAX_LINE, max_size=MAX_LINE + 50)),
                   max_size=20)


def sim() -> tuple[VirtualClock, MCR501Simulator]:
    clock = VirtualClock()
    return clock, MCR501Simulator(clock, SimConfig(start_gap=10e-3, lower_angle=0.8))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(stream=streams, pauses=st.lists(st.floats(0.0, 5.0), min_size=20, max_size=20))
def test_any_bytes_are_answered_or_dropped_and_the_instrument_still_answers(
        stream: list[bytes], pauses: list[float]) -> None:
    clock, simulator = sim()
    splitter = LineSplitter(MAX_LINE)
    for chunk, pause in zip(stream, pauses, strict=False):
        for reply in replies_to(chunk, splitter, simulator):
            assert "\r" not in reply and "\n" not in reply
            reply.encode("ascii")  # the reply is a line of the dialect
            error = ERROR.decode(reply) if reply.startswith("#ERR") else None
            if error is not None:  # no internal failure dressed as an #ERR
                assert "internal" not in str(error["text"]), reply
        clock.sleep(pause)
    # whatever came before, a terminated valid request is answered
    replies = replies_to(b"\r\n#VERS[?]\r\n", splitter, simulator)
    assert replies[-1].startswith("#VERS[MCR501;"), replies


def test_a_served_mcr501_answers_after_garbage() -> None:
    _clock, simulator = sim()
    with SimulatorServer(simulator) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=5) as conn:
        conn.sendall(b"\xff\x00:ROT[CW;1e999]\r:GAP[nan]\n:RUN[-0]\r\n" + b"x" * 5000
                     + b"\r\n#VERS[?]\r\n")
        seen = b""
        while b"#VERS[" not in seen:
            data = conn.recv(4096)
            assert data, seen
            seen += data
        assert seen.count(b"#ERR[") >= 4, seen


def test_a_failing_handler_is_logged_and_answered(caplog, monkeypatch) -> None:
    _clock, simulator = sim()

    def broken(*args: object) -> list[str]:
        raise ZeroDivisionError("a bug")

    monkeypatch.setitem(simulator._handlers, "read_gap", broken)
    assert simulator.handle(":GAP[?]") == ["#ERR[11;bad argument (internal ZeroDivisionError)]"]
    assert "handling ':GAP[?]' failed" in caplog.text
    assert simulator.handle("#VERS[?]")[0].startswith("#VERS[MCR501;")
