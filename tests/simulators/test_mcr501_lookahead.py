"""Streaming reads served from the look-ahead give what integrating to each read gives.

Two cells get the same commands at the same times; one advances with ``ahead=True`` on its
reads (as the simulator does), the other integrates only to each read. Samples, trips and
the overflow flag must agree: times, angles and gaps exactly (motion only), forces to
rounding (the contact is stepped in other blocks).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from gelrig.simulators.mcr501 import Sample, ShearCell, SimConfig

DELTA = 0.78e-3

Op = Callable[[ShearCell, bool], None]


def _cell(**changes: object) -> ShearCell:
    cfg = SimConfig(torque_offset=0.0, acceleration=50.0)
    start = cfg.lower_angle - 1.2e-3 / cfg.arm
    return ShearCell(replace(cfg, start_angle=start, start_gap=cfg.touch_gap + 0.2e-3,
                             **changes), 0.0)  # type: ignore[arg-type]


def _script(read_every: float, extra: list[tuple[float, Op]]) -> list[tuple[float, Op]]:
    """A pass through contact: stream, lower into contact, turn, stop, lift, reads between."""
    cfg = SimConfig()
    ops: list[tuple[float, Op]] = [
        (0.0, lambda c, a: c.start_stream(0.0, 0.05)),
        (0.1, lambda c, a: c.set_gap(0.1, cfg.touch_gap - DELTA)),
        (2.0, lambda c, a: c.set_speed(2.0, 1.19e-4 / cfg.arm)),
        (19.0, lambda c, a: c.set_speed(19.0, 0.0)),
        (21.3, lambda c, a: c.set_gap(21.3, cfg.touch_gap + 1e-3)),
        (40.0, lambda c, a: c.stop_stream(40.0)),
    ]
    t = read_every
    while t < 40.0:
        ops.append((t, lambda c, a, t=t: c.advance(t, ahead=a)))
        t = round(t + read_every, 9)
    ops += extra
    return sorted(ops, key=lambda op: op[0])


def _run(cell: ShearCell, ops: list[tuple[float, Op]], ahead: bool) -> list[Sample]:
    """Apply the script, draining the samples at each read as the simulator does."""
    got: list[Sample] = []
    for t, op in ops:
        op(cell, ahead)
        if cell.streaming and t > 0:
            got += cell.samples
            cell.samples.clear()
    return got


def _same(a: list[Sample], b: list[Sample]) -> None:
    assert len(a) == len(b)
    x, y = np.array(a), np.array(b)
    for col in (0, 1, 4):  # t, angle, gap: motion only, to the bit
        assert np.array_equal(x[:, col], y[:, col])
    for col in (2, 3):  # torque, normal force: the contact, to rounding
        np.testing.assert_allclose(x[:, col], y[:, col], rtol=1e-12, atol=1e-18)
    assert np.max(np.abs(x[:, 3])) > 0.05  # the pass really went through contact


@pytest.mark.parametrize("read_every", [0.3, 1.7])
def test_reads_from_the_look_ahead_equal_reads_to_each_time(read_every: float) -> None:
    ops = _script(read_every, [])
    plain, ahead = _cell(), _cell()
    _same(_run(plain, ops, False), _run(ahead, ops, True))
    assert plain.t_int == ahead.t_int


def test_a_single_reading_between_reads_returns_to_the_clock() -> None:
    """forces() mid-stream (a :TORQ? request) and reads after it change nothing."""
    extra: list[tuple[float, Op]] = [
        (t, lambda c, a, t=t: c.forces(t)) for t in (5.05, 9.3, 12.0)]
    ops = _script(0.7, extra)
    plain, ahead = _cell(), _cell()
    _same(_run(plain, ops, False), _run(ahead, ops, True))


def test_a_trip_is_found_at_the_same_node_with_look_ahead() -> None:
    ops = _script(0.9, [])
    plain, ahead = _cell(overlap_limit=0.7e-3), _cell(overlap_limit=0.7e-3)
    _same(_run(plain, ops, False), _run(ahead, ops, True))
    assert plain.trips and plain.trips == ahead.trips


def test_the_buffer_overflows_alike_when_reads_stop() -> None:
    """Reads every 0.5 s, none between 4 s and 30 s: the oldest samples are dropped alike."""
    ops = [op for op in _script(0.5, []) if not 4.0 < op[0] < 30.0]
    plain, ahead = _cell(stream_buffer=100), _cell(stream_buffer=100)
    for t, op in ops:
        if t > 30.0:
            break
        op(plain, False)
        op(ahead, True)
        assert plain.overflowed == ahead.overflowed
        assert [s.t for s in plain.samples] == [s.t for s in ahead.samples]
        if t < 4.0:
            plain.samples.clear()
            ahead.samples.clear()
    assert plain.overflowed and len(plain.samples) == 100
