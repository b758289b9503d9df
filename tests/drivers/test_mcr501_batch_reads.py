"""Stream records read in batches (issue 31 item 1, docs/decisions/0393): the same bytes on the
wire and the same records as one pyvisa read per line, in far fewer reads."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from gelrig.drivers.mcr501 import MCR501, VisaTransport
from gelrig.drivers.mcr501.codec import RECORD_MIN_LENGTH, record_rest
from gelrig.drivers.mcr501.commands import RECORD
from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer
from tests.faultproxy import FaultProxy


def _one_read_per_line(self: VisaTransport, n: int, *bounds: object) -> list[str]:
    return [self.read_line() for _ in range(n)]


def _session(rm: Any, monkeypatch: pytest.MonkeyPatch) -> tuple[list[np.ndarray], bytes, bytes,
                                                                 int]:
    """A stream session through a recording relay: records, requests, replies, VISA reads."""
    reads = 0
    visa_read: Callable[..., Any] = rm.visalib.read

    def counted(*args: Any, **kwargs: Any) -> Any:
        nonlocal reads
        reads += 1
        return visa_read(*args, **kwargs)

    monkeypatch.setattr(rm.visalib, "read", counted)
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True, seed=7))
    with SimulatorServer(sim) as server, FaultProxy(server.port, lifetime=60) as proxy:
        drv = MCR501(f"TCPIP0::127.0.0.1::{proxy.port}::SOCKET", clock,
                     resource_manager=rm).open()
        try:
            drv.set_gap(sim.config.touch_gap - 0.5e-3)  # in contact: torque and force vary
            drv.start_stream(0.02)
            drv.rotate(4e-3)
            blocks = []
            for span in (7.3, 0.01, 0.5, 4.0):  # 365 records (4 replies), none, 25, 200
                keep_moving(clock, drv, span, drv.config.motion_bound)
                blocks.append(drv.read_stream())
            drv.stop_stream()
        finally:
            drv.close()
        monkeypatch.undo()
        proxy.stop()
        columns = [np.concatenate([getattr(b, name) for b in blocks])
                   for name in ("t", "angle", "theta", "torque", "normal_force", "gap")]
        return columns, bytes(proxy.requests), bytes(proxy.replies), reads


def test_batched_reads_carry_the_same_bytes_and_records_in_fewer_reads(
        rm: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    batched = _session(rm, monkeypatch)
    monkeypatch.setattr(VisaTransport, "read_lines", _one_read_per_line)
    per_line = _session(rm, monkeypatch)
    assert batched[1] == per_line[1]  # every request byte
    assert batched[2] == per_line[2]  # every reply byte
    assert per_line[2].count(b":MEAS[") == batched[0][0].size == 590
    for mine, theirs in zip(batched[0], per_line[0], strict=True):
        assert np.array_equal(mine, theirs)
    # one VISA read per record line before; now a few per reply of up to 100 records
    assert batched[3] < per_line[3] - 500


class _Wire:
    """A VISA resource stand-in holding the bytes of one reply; it fails any read that asks
    for more bytes than are left (a real one would wait for them until its timeout)."""

    def __init__(self, data: bytes):
        self.data = data
        self.asked: list[int] = []
        self.termchar = True

    def read_bytes(self, count: int) -> bytes:
        assert not self.termchar
        assert count <= len(self.data), f"asked {count} bytes, {len(self.data)} left"
        self.asked.append(count)
        out, self.data = self.data[:count], self.data[count:]
        return out

    def set_visa_attribute(self, name: Any, state: bool) -> None:
        self.termchar = state


class _Manager:
    def __init__(self, wire: _Wire):
        self.wire = wire

    def open_resource(self, *args: Any, **kwargs: Any) -> _Wire:
        return self.wire


@pytest.mark.parametrize("extra", [[0] * 9, [0, 7, 1, 30, 0, 2, 0, 0, 11], [40] * 9])
def test_read_lines_never_asks_past_the_reply(extra: list[int]) -> None:
    """Lines of the shortest length and longer ones, terminations split across reads: the
    lines come back whole and every read stays within the reply."""
    lines = [":" + "9" * (RECORD_MIN_LENGTH - 1 + k) for k in extra]
    wire = _Wire("".join(f"{line}\r\n" for line in lines).encode() + b"NEXT")
    transport = VisaTransport("TCPIP0::127.0.0.1::1::SOCKET", resource_manager=_Manager(wire))
    assert transport.read_lines(len(lines), RECORD_MIN_LENGTH) == lines
    assert wire.data == b"NEXT" and wire.termchar
    if not any(extra):
        assert len(wire.asked) == 1  # all at the shortest length: one read


def test_record_rest_is_a_lower_bound_on_every_prefix_of_a_record() -> None:
    """For every prefix of records of all lengths and signs: no more than is left, at least 1,
    and whole lines no shorter than RECORD_MIN_LENGTH."""
    rng = np.random.default_rng(5)
    scales = 10.0 ** rng.integers(-3, 7, size=(300, 5))
    rows = rng.uniform(-1, 1, size=(300, 5)) * scales
    rows[:20] = 0.0
    exact_hits = 0
    for row in rows:
        line = (RECORD.encode_row(*row) + "\r\n").encode()
        assert len(line) - 2 >= RECORD_MIN_LENGTH
        for k in range(1, len(line)):
            due = record_rest(line[:k])
            assert 1 <= due <= len(line) - k, (line, k, due)
            exact_hits += due == len(line) - k
    assert exact_hits > 300 * 10  # tight: exact within the last field's decimals at least


def test_stream_reads_through_the_fake_wire_use_the_record_bound() -> None:
    lines = [RECORD.encode_row(12.5 + k, -3.25 * k, 0.001, 4e3 * k, 2.3) for k in range(100)]
    wire = _Wire("".join(f"{line}\r\n" for line in lines).encode())
    transport = VisaTransport("TCPIP0::127.0.0.1::1::SOCKET", resource_manager=_Manager(wire))
    assert transport.read_lines(len(lines), RECORD_MIN_LENGTH, record_rest) == lines
    assert wire.data == b"" and len(wire.asked) <= 8
