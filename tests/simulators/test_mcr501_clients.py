"""The simulated MCR 501 as a scientist's own pyvisa script meets it (issue 13).

The client here is plain pyvisa + pyvisa-py with literal request strings, not gelrig's driver
or codec: line ends, one client at a time, the bounded stream buffer and the bounded input line
(docs/decisions/0110). Every read has a timeout, so a missing reply fails instead of hanging.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
import pyvisa
from pyvisa.errors import VisaIOError

from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer

VERS = "#VERS[MCR501;SN80000000;03.40]"
OVERFLOW = 0x20
BUFFER = 4096  # points, docs/decisions/0110


@dataclass
class Bench:
    clock: VirtualClock
    sim: MCR501Simulator
    server: SimulatorServer
    rm: Any

    def open(self, write_termination: str = "\r\n", timeout_ms: int = 2000) -> Any:
        """A pyvisa session as a script would open it."""
        return self.rm.open_resource(
            self.server.resource,
            read_termination="\r\n",
            write_termination=write_termination,
            timeout=timeout_ms,
        )


@pytest.fixture(scope="module")
def rm() -> Iterator[Any]:
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


@pytest.fixture
def bench(rm: Any) -> Iterator[Bench]:
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig())
    with SimulatorServer(sim) as server:
        yield Bench(clock, sim, server, rm)


@pytest.fixture
def client(bench: Bench) -> Iterator[Any]:
    res = bench.open()
    yield res
    res.close()


def _nothing_more(res: Any) -> bool:
    """True if no further line arrives within 0.2 s."""
    timeout = res.timeout
    res.timeout = 200
    try:
        res.read()
    except VisaIOError:
        return True
    finally:
        res.timeout = timeout
    return False


# -- line ends ------------------------------------------------------------------------------


@pytest.mark.parametrize("end", ["\r\n", "\r", "\n"], ids=["CRLF", "CR", "LF"])
def test_each_line_end_is_answered_with_cr_lf(bench: Bench, end: str) -> None:
    res = bench.open(write_termination=end)
    try:
        for request, reply in (
            ("#VERS[?]", VERS.encode()),
            (":STAT[?]", b":STAT[IDLE;0000]"),
            (":ANG[?]", b":ANG[0.0000000]"),
        ):
            res.write(request)
            assert res.read_raw() == reply + b"\r\n"
        assert _nothing_more(res)  # the empty line inside CR LF is not answered
    finally:
        res.close()


def test_mixed_line_ends_in_one_write(client: Any) -> None:
    client.write_raw(b":STAT[?]\r#VERS[?]\n:ANG[?]\r\n\r\n\n")
    assert [client.read() for _ in range(3)] == [":STAT[IDLE;0000]", VERS, ":ANG[0.0000000]"]
    assert _nothing_more(client)


@pytest.mark.parametrize(
    ("request_", "reply"),
    [
        (":FOO[]", "#ERR[10;unknown command :FOO]"),
        ("VERS?", "#ERR[10;unknown command]"),
        (":ROT[LEFT;1]", "#ERR[11;bad argument for :ROT]"),
        (":GAP[1.0]", "#ERR[12;gap not referenced, send :GAPZ() first]"),
        (":ROT[CW;1e3]", "#ERR[13;speed 1000 rpm outside (0, 100)]"),
        (":RUN[0]", "#ERR[13;interval 0 s outside (0.001, 3600)]"),
    ],
)
def test_bad_requests_get_named_errors(client: Any, request_: str, reply: str) -> None:
    assert client.query(request_) == reply
    assert client.query("#VERS[?]") == VERS  # and the session carries on


def test_non_ascii_bytes_get_a_named_error(client: Any) -> None:
    client.write_raw(b"#VERS[\xff]\r\n")
    assert client.read() == "#ERR[10;non-ASCII bytes]"


def test_other_read_terminations_see_the_cr_lf(bench: Bench) -> None:
    res = bench.open()
    try:
        res.read_termination = "\n"
        assert res.query("#VERS[?]") == VERS + "\r"
        res.read_termination = "\r"
        assert res.query("#VERS[?]") == VERS
        assert res.query(":STAT[?]") == "\n:STAT[IDLE;0000]"
    finally:
        res.close()


# -- one client at a time -------------------------------------------------------------------


def test_a_second_client_is_refused_while_the_first_keeps_control(bench: Bench) -> None:
    first = bench.open()
    try:
        assert first.query(":ROT[CW;1.000000e+00]") == ":ROT[OK]"
        second = bench.open(timeout_ms=2000)
        try:
            assert re.fullmatch(r"#ERR\[20;[^\[\];]*busy[^\[\];]*\]", second.read())
            with contextlib.suppress(VisaIOError):
                second.write(":STOP[]")
            assert _nothing_more(second)  # closed: the stop got no answer ...
        finally:
            second.close()
        assert ":STOP[]" not in bench.sim.log  # ... and never reached the instrument
        assert first.query(":STAT[?]").startswith(":STAT[ROT;")
        assert bench.sim.cell.spin.target > 0
    finally:
        first.close()


def test_control_passes_to_the_next_client_once_the_first_closes(bench: Bench) -> None:
    first = bench.open()
    assert first.query(":GAPZ[]") == ":GAPZ[OK]"
    first.close()
    second = bench.open()
    try:
        assert second.query("#VERS[?]") == VERS
        assert second.query(":STAT[?]") == ":STAT[IDLE;0002]"  # same instrument, referenced
    finally:
        second.close()


# -- bounded stream buffer ------------------------------------------------------------------


def _status_flags(res: Any) -> int:
    m = re.fullmatch(r":STAT\[(IDLE|ROT|HOLD);([0-9A-F]{4})\]", res.query(":STAT[?]"))
    assert m is not None
    return int(m.group(2), 16)


def _drain(res: Any) -> list[float]:
    """The times of every point the stream holds, read as ``#DATA[?]`` batches."""
    times: list[float] = []
    for _ in range(1000):  # bounded: 1000 batches of up to 100 points
        m = re.fullmatch(r"#DATA\[(\d+);(\d+)\]", res.query("#DATA[?]"))
        assert m is not None
        for _ in range(int(m.group(1))):
            rec = re.fullmatch(r":MEAS\[([-\d.]+);[^\]]*\]", res.read())
            assert rec is not None
            times.append(float(rec.group(1)))
        if int(m.group(2)) == 0:
            return times
    raise AssertionError("stream never drained")


def test_an_unread_stream_overflows_and_keeps_the_newest_points(
    bench: Bench, client: Any
) -> None:
    assert bench.sim.config.stream_buffer == BUFFER
    assert client.query(":RUN[0.001]") == ":RUN[OK]"
    bench.clock.sleep(6.0)  # 6000 points at the fastest interval
    assert _status_flags(client) & OVERFLOW
    times = _drain(client)
    assert len(times) == BUFFER
    assert times[0] == pytest.approx(6.0 - (BUFFER - 1) * 1e-3)  # the oldest were dropped
    assert times[-1] == pytest.approx(6.0)
    assert _status_flags(client) & OVERFLOW  # latched: draining and reading do not clear it
    assert client.query(":RUN[0.001]") == ":RUN[OK]"
    assert not _status_flags(client) & OVERFLOW  # a restart does


def test_stopping_the_stream_clears_the_overflow_flag(bench: Bench, client: Any) -> None:
    assert client.query(":RUN[0.001]") == ":RUN[OK]"
    bench.clock.sleep(5.0)
    assert _status_flags(client) & OVERFLOW
    assert client.query(":END[]") == ":END[OK]"
    assert not _status_flags(client) & OVERFLOW
    assert client.query("#DATA[?]") == "#DATA[0;0]"


def test_a_stream_read_in_time_never_overflows(bench: Bench, client: Any) -> None:
    assert client.query(":RUN[0.001]") == ":RUN[OK]"
    total = 0
    for _ in range(6):
        bench.clock.sleep(1.0)
        total += len(_drain(client))
        assert not _status_flags(client) & OVERFLOW
    assert total == 6000


# -- bounded input line ---------------------------------------------------------------------


def test_an_over_long_unterminated_line_is_dropped_with_one_error(
    bench: Bench, client: Any
) -> None:
    client.write_raw(b"#VERS[?]" + b"x" * 100_000)  # no line end
    assert client.read() == "#ERR[11;line too long, at most 256 bytes]"
    handled = bench.sim.requests
    client.write_raw(b"y" * 1000 + b"\r\n")  # the rest of that line, then its end
    assert client.query("#VERS[?]") == VERS  # no second error in between
    assert bench.sim.requests == handled + 1  # the tail never reached the instrument
    assert _nothing_more(client)


def test_the_line_bound_is_256_bytes(client: Any) -> None:
    longest = ":RUN[" + "0" * 249 + "1]"  # a valid request of exactly 256 bytes
    assert len(longest) == 256
    assert client.query(longest) == ":RUN[OK]"
    assert client.query(":RUN[0" + longest[5:]) == "#ERR[11;line too long, at most 256 bytes]"
    assert client.query(":STAT[?]").startswith(":STAT[IDLE;")


# ---- time-limited rotation (docs/decisions/0201) ------------------------------------------

def _stat(res: Any) -> tuple[str, int]:
    mode, flags = res.query(":STAT[?]")[6:-1].split(";")
    return mode, int(flags, 16)


def _angle(res: Any) -> float:
    return float(res.query(":ANG[?]")[5:-1])


def test_a_time_limited_rotation_ends_by_itself(bench: Bench, client: Any) -> None:
    assert client.query(":ROT[CW;1.000000e+00;1.5]") == ":ROT[OK]"
    bench.clock.sleep(1.4)
    assert _stat(client) == ("ROT", 0)
    bench.clock.sleep(0.2)  # past the end: ramping down as after :STOP[] (0x08)
    assert _stat(client) == ("IDLE", 0x08)
    bench.clock.sleep(1.0)
    assert _stat(client) == ("IDLE", 0)
    rest = _angle(client)
    # 1 rpm: ramps up and down at 0.5 rad/s^2 (0.21 s each) around 1.5 s of turning, which
    # covers the angle of 1.5 s at full speed
    omega = 2 * 3.141592653589793 / 60
    assert rest == pytest.approx(57.29577951 * omega * 1.5, abs=2e-6)
    bench.clock.sleep(10.0)
    assert _angle(client) == rest


def test_the_same_rotation_again_renews_it(bench: Bench, client: Any) -> None:
    assert client.query(":ROT[CCW;5.000000e-01;1.5]") == ":ROT[OK]"
    for _ in range(8):  # renewed every second for 8 s: turning all along
        bench.clock.sleep(1.0)
        assert _stat(client)[0] == "ROT"
        assert client.query(":ROT[CCW;5.000000e-01;1.5]") == ":ROT[OK]"
    assert bench.sim.renewals == 8
    bench.clock.sleep(1.6)  # not renewed: it stops 1.5 s after the last one
    assert _stat(client)[0] == "IDLE"
    # a new speed is a new rotation, not a renewal
    assert client.query(":ROT[CW;5.000000e-01;1.5]") == ":ROT[OK]"
    assert client.query(":ROT[CW;6.000000e-01;1.5]") == ":ROT[OK]"
    assert bench.sim.renewals == 8
    assert client.query(":STOP[]") == ":STOP[OK]"
    bench.clock.sleep(3.0)
    assert _stat(client) == ("IDLE", 0)


def test_a_rotation_ended_while_nobody_asked_ends_at_its_own_time(bench: Bench) -> None:
    """The client that turned the arm goes away; one that comes 60 s later reads the arm
    where the rotation's end left it, not where it would be had it turned on."""
    first = bench.open()
    assert first.query(":ROT[CW;2.000000e+00;1.5]") == ":ROT[OK]"
    bench.clock.sleep(0.5)
    moving = _angle(first)
    first.close()
    bench.clock.sleep(60.0)
    second = bench.open()
    try:
        assert _stat(second) == ("IDLE", 0)
        omega = 2 * 2 * 3.141592653589793 / 60
        ramp = omega / 0.5
        # from 0.5 s: 1.0 s more at full speed, then the ramp down (half the speed on average)
        assert _angle(second) - moving == pytest.approx(
            57.29577951 * omega * (1.0 + ramp / 2), abs=1e-5)
    finally:
        second.close()


def test_time_limited_rotation_arguments(client: Any) -> None:
    allowed = "allowed 0 < duration <= 3600 s]"
    assert client.query(":ROT[CW;1.0;0]") == f"#ERR[13;duration 0 s, {allowed}"
    assert client.query(":ROT[CW;1.0;4000]") == f"#ERR[13;duration 4000 s, {allowed}"
    assert client.query(":ROT[CW;1e3;1.5]").startswith("#ERR[13;speed 1000 rpm")
    assert client.query(":ROT[CW;1.0;-1]") == f"#ERR[13;duration -1 s, {allowed}"
    assert client.query(":ROT[CW;1.0;x]") == "#ERR[11;bad argument for :ROT]"
