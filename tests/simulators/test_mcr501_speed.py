"""The MCR 501 fast paths (issue 12, rehearsal speed) compute exactly what the plain ones do.

Each fast path is checked against the straightforward form it replaced, to the last bit; and
the paper shear rehearsal against figures recorded before the fast paths existed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gelrig.drivers.mcr501.codec import (
    RequestError,
    decode_record,
    decode_record_row,
    decode_request,
)
from gelrig.drivers.mcr501.commands import COMMANDS, ERROR, RECORD, Message
from gelrig.instrument.core.errors import DeviceErrorReply, FramingError
from gelrig.instrument.physics.contact import _irregular, _step_weight
from gelrig.simulators.mcr501.instrument import MCR501Simulator
from gelrig.simulators.mcr501.motion import Lift, Spin
from gelrig.simulators.mcr501.physics import Sample, _sorted_unique

REFERENCE = Path(__file__).parent / "data" / "shear_rehearsal_reference.json"


def plain_encode(message: Message, values: dict[str, object]) -> str:
    assert not isinstance(message.shape, str)
    body = ";".join(format(values[f.name], f.fmt) for f in message.shape)
    return f"{message.key}[{body}]"


def plain_decode(message: Message, line: str) -> dict[str, object] | None:
    m = message.regex.match(line)
    if m is None or isinstance(message.shape, str):
        return None if m is None else {}
    raw = m.groupdict()
    return {f.name: f.decode(raw[f.name]) for f in message.shape}


def test_records_encode_and_decode_as_the_per_field_formats_do() -> None:
    rng = np.random.default_rng(7)
    names = [f.name for f in RECORD.shape]  # type: ignore[union-attr]
    for row in rng.normal(size=(2000, 5)) * rng.choice([1e-6, 1.0, 1e3, 1e6], size=(2000, 5)):
        values = dict(zip(names, row.tolist(), strict=True))
        line = RECORD.encode(**values)
        assert line == plain_encode(RECORD, values) == RECORD.encode_row(*row.tolist())
        assert RECORD.decode(line) == plain_decode(RECORD, line) == decode_record(line)
        assert decode_record_row(line) == tuple(plain_decode(RECORD, line).values())  # type: ignore[union-attr]


def test_every_table_message_round_trips_as_before() -> None:
    samples: dict[str, object] = {"model": "MCR501", "serial": "SN1", "firmware": "03.40",
                                  "mode": "ROT", "flags": 0x2A, "direction": "CCW",
                                  "count": 3, "remaining": 0, "code": 13, "text": "x y"}
    for command in COMMANDS.values():
        for message in (command.request, command.reply):
            if isinstance(message.shape, str):
                line = message.encode()
                assert line == f"{message.key}[{message.shape}]"
                assert message.decode(line) == {}
                continue
            values = {f.name: samples.get(f.name, 1.2345678) for f in message.shape}
            line = message.encode(**values)
            assert line == plain_encode(message, values)
            assert message.decode(line) == plain_decode(message, line)
            assert message.decode(line + "x") is None
    with pytest.raises(TypeError):
        RECORD.encode(t_s=1.0)
    with pytest.raises(TypeError):
        RECORD.encode_row(1.0, 2.0)


def test_the_record_row_keeps_the_codec_validation() -> None:
    with pytest.raises(DeviceErrorReply):
        decode_record_row(ERROR.encode(code=11, text="bad argument"))
    for bad in (":MEAS[1;2;3;4]", ":MEAS[1;2;3;4;x]", ":MEAS[1;2;3;4;5", "#DATA[1;0]"):
        with pytest.raises(FramingError):
            decode_record_row(bad)


def test_requests_are_found_by_key_as_by_scanning_the_table() -> None:
    line = COMMANDS["set_gap"].request.encode(gap_mm=1.5)
    assert decode_request(line)[0] is COMMANDS["set_gap"]
    assert decode_request(":GAP[?]")[0] is COMMANDS["read_gap"]
    for bad, code in ((":GAP[x]", 11), (":NOPE[?]", 10), ("garbage", 10)):
        with pytest.raises(RequestError) as info:
            decode_request(bad)
        assert info.value.code == code


def test_scalar_motion_states_equal_the_array_evaluation() -> None:
    rng = np.random.default_rng(3)
    for _ in range(300):
        spin = Spin(*rng.normal(size=4).tolist(), float(rng.uniform(0.1, 2)))
        lift = Lift(float(rng.normal()), float(rng.uniform(0, 0.01)),
                    float(rng.uniform(0, 0.01)), float(rng.uniform(1e-4, 1e-2)))
        times = spin.t0 + rng.uniform(0, 10, size=20)
        phi, omega = spin.at(times)
        gap = lift.at(lift.t0 + (times - spin.t0))
        for i, t in enumerate(times.tolist()):
            assert spin.state(t) == (phi[i], omega[i])
            assert lift.gap(lift.t0 + (t - spin.t0)) == gap[i]
        assert spin.peak_speed(spin.t0, spin.t0 + 3.0) == float(
            np.max(np.abs(spin.at(np.array([spin.t0, spin.t0 + 3.0]))[1])))


def test_sorted_unique_is_np_unique() -> None:
    rng = np.random.default_rng(5)
    for n in (0, 1, 2, 17, 500):
        values = np.round(rng.uniform(0, 5, size=n), 1)
        assert np.array_equal(_sorted_unique(values), np.unique(values))


def plain_irregular(r: np.ndarray, x: np.ndarray, x_prev: float, h_prev: float) -> np.ndarray:
    """gelrig.instrument.physics.contact._irregular as it was before its fast path."""
    dx = np.diff(x, prepend=x_prev)
    u = _step_weight(r) * dx
    out = np.empty(x.size)
    cum = np.cumsum(r)
    start = 0
    while start < x.size:
        end = int(np.searchsorted(cum, cum[start] + 20.0, side="right"))
        end = max(end, start + 1)
        lo = cum[start:end] - cum[start]
        first = math.exp(-r[start]) * h_prev + u[start]
        growth = np.exp(lo[1:])
        acc = first + np.concatenate(([0.0], np.cumsum(u[start + 1 : end] * growth)))
        out[start:end] = acc * np.exp(-lo)
        h_prev = float(out[end - 1])
        start = end
    return out


@pytest.mark.parametrize("scale", [1e-4, 1.0, 30.0])
def test_the_irregular_recursion_is_unchanged(scale: float) -> None:
    rng = np.random.default_rng(11)
    for _ in range(50):
        n = int(rng.integers(1, 400))
        r = rng.uniform(0, 1, size=n) * scale
        r[rng.uniform(size=n) < 0.05] = 0.0  # zero steps take the guarded weight
        x = np.abs(rng.normal(size=n)) * 1e-5
        args = (r, x, float(rng.uniform(0, 1e-5)), float(rng.normal() * 1e-6))
        assert np.array_equal(_irregular(*args), plain_irregular(*args))
        r = np.abs(r) + 1e-9  # every step positive
        args = (r, *args[1:])
        assert np.array_equal(_irregular(*args), plain_irregular(*args))


def test_stream_noise_drawn_per_batch_equals_per_point_draws() -> None:
    from gelrig.instrument.core.clock import VirtualClock

    sim = MCR501Simulator(VirtualClock())
    rng = np.random.default_rng(0)
    batch = [Sample(0.1 * k, *rng.normal(size=2).tolist(), float(rng.normal()), 3e-3)
             for k in range(1, 60)]
    sim.cell.samples[:] = batch
    lines = sim._read_stream(COMMANDS["read_stream"], {}, 0.0)[1:]
    point_rng = np.random.default_rng(sim.config.seed)
    expected = [
        plain_encode(RECORD, {
            "t_s": s.t, "angle_deg": math.degrees(s.angle),
            "torque_mnm": sim.measured_torque(s.torque, point_rng) * 1e3,
            "force_n": sim.measured_force(s.normal_force, point_rng), "gap_mm": s.gap * 1e3})
        for s in batch
    ]
    assert lines == expected


def rehearsal_figures(**simulator: object) -> dict[str, object]:
    """The paper shear rehearsal on the built-in rig's twin (``simulator`` entries of the
    rig file overridden): lab times, sizes, and per-column figures of every sample block."""
    import copy

    from gelrig.factory import build_twin
    from gelrig.instrument.core.fields import read_toml
    from gelrig.protocols.events import EventBus, Samples
    from gelrig.protocols.rehearsal import describe, rehearse
    from gelrig.protocols.rigfile import default_rig, parse_rig
    from gelrig.protocols.spec import load_protocol, paper_protocol

    table = copy.deepcopy(read_toml(default_rig("shear"), "rig file"))
    table["simulator"].update(simulator)
    twin = build_twin(parse_rig(table, "shear rig"))
    bus = EventBus()
    blocks: list[dict[str, np.ndarray]] = []
    bus.subscribe(lambda e: blocks.append(dict(e.data)) if isinstance(e, Samples) else None)
    try:
        report = describe(rehearse(twin, load_protocol(paper_protocol("shear")), bus))
    finally:
        twin.close()
    assert report["state"] == "completed"
    columns = {}
    for column in blocks[0]:
        v = np.concatenate([b[column] for b in blocks])
        columns[column] = {"sum": float(np.sum(v)), "sum_abs": float(np.sum(np.abs(v))),
                           "first": float(v[0]), "last": float(v[-1]),
                           "min": float(np.min(v)), "max": float(np.max(v))}
    return {"lab_time_s": report["lab_time_s"], "samples": report["samples"],
            "bytes": report["bytes"],
            "steps": [{k: s[k] for k in ("name", "samples", "lab_time_s", "travel_m")}
                      for s in report["steps"]],
            "columns": columns}


@pytest.mark.slow
@pytest.mark.parametrize(("key", "simulator"), [
    ("shear", {}),  # fresh contact per pass: recorded when it became the default (issue 14)
    ("shear_carry_history", {"carry_history": True}),  # recorded before the fast paths
])
def test_the_paper_shear_rehearsal_is_what_it_was(key: str, simulator: dict) -> None:
    """Fast paths change nothing: the rehearsal reproduces figures recorded earlier, to 1e-12.
    With ``carry_history`` (the old default) it still gives the figures of issue 12."""
    expected = json.loads(REFERENCE.read_text())[key]
    got = rehearsal_figures(**simulator)
    assert got["lab_time_s"] == pytest.approx(expected["lab_time_s"], rel=1e-12, abs=0)
    assert (got["samples"], got["bytes"]) == (expected["samples"], expected["bytes"])
    for g, want in zip(got["steps"], expected["steps"], strict=True):  # type: ignore[call-overload]
        assert (g["name"], g["samples"]) == (want["name"], want["samples"])
        assert g["lab_time_s"] == pytest.approx(want["lab_time_s"], rel=1e-12, abs=0)
        assert g["travel_m"] == pytest.approx(want["travel_m"], rel=1e-12, abs=0)
    for column, figures in expected["columns"].items():
        for name, want in figures.items():
            value = got["columns"][column][name]  # type: ignore[index]
            assert value == pytest.approx(want, rel=1e-12, abs=1e-300, nan_ok=True), (column, name)


# -- the batch paths of the driver (issue 12, i12-finish) ------------------------------------

def _records(n: int, seed: int = 3) -> list[str]:
    rng = np.random.default_rng(seed)
    return [RECORD.encode_row(*v) for v in rng.uniform(-500, 500, (n, 5)).tolist()]


@pytest.mark.parametrize("n", [1, 2, 17, 100])
def test_a_batch_of_records_decodes_as_each_record_does(n: int) -> None:
    from gelrig.drivers.mcr501.codec import decode_record_rows

    lines = _records(n)
    assert decode_record_rows(lines) == [v for line in lines for v in decode_record_row(line)]
    assert decode_record_rows([]) == []


@pytest.mark.parametrize("bad", [
    ERROR.encode(code=32, text="torque over range"), ":MEAS[1;2;3;4]", ":MEAS[1;2;3;4;x]",
    "#DATA[1;0]", ":MEAS[1;2;3;4;5]\n:MEAS[1;2;3;4;5]",
])
def test_a_batch_with_a_bad_record_raises_what_that_record_raises(bad: str) -> None:
    from gelrig.drivers.mcr501.codec import decode_record_rows

    lines = _records(5)
    lines[3] = bad
    with pytest.raises(DeviceErrorReply if bad.startswith("#ERR") else FramingError):
        decode_record_rows(lines)


def test_literal_requests_and_the_stream_header_decode_as_the_generic_path() -> None:
    from gelrig.drivers.mcr501.codec import _decode_request, decode_reply, decode_stream_header

    for command in COMMANDS.values():
        if isinstance(command.request.shape, str):
            line = command.request.encode()
            assert decode_request(line) == _decode_request(line) == (command, {})
    header = COMMANDS["read_stream"]
    for count, remaining in ((0, 0), (100, 4096), (7, 0)):
        line = header.reply.encode(count=count, remaining=remaining)
        values = decode_reply(header, line)
        assert decode_stream_header(line) == (values["count"], values["remaining"])
    with pytest.raises(FramingError):
        decode_stream_header("#DATA[1]")
    with pytest.raises(DeviceErrorReply):
        decode_stream_header(ERROR.encode(code=11, text="bad argument"))


def test_the_driver_block_equals_the_per_point_conversion() -> None:
    """What read_stream computes on columns is what it computed one point at a time."""
    from gelrig.drivers.mcr501 import MCR501
    from gelrig.instrument.contracts.bounded_motion import keep_moving
    from gelrig.instrument.contracts.rheometer import StreamBlock
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.simulators.mcr501 import DirectLink, SimConfig

    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True))
    link = DirectLink(sim)
    drv = MCR501(link, clock).open()
    clock.sleep(2.0)
    t0 = clock.now()
    drv.start_stream(0.01)
    drv.rotate(1e-3)
    keep_moving(clock, drv, 3.3, drv.config.motion_bound)  # ~330 points: four #DATA batches
    sent: list[str] = []
    real = link.read_lines
    link.read_lines = lambda n, *bounds: sent.extend(real(n, *bounds)) or sent[-n:]  # type: ignore[method-assign]
    block = drv.read_stream()
    drv.close()
    assert isinstance(block, StreamBlock) and len(block) == len(sent) > 300
    arm = drv.config.arm
    for point, line in zip(block, sent, strict=True):
        t_s, angle_deg, torque_mnm, force_n, gap_mm = decode_record_row(line)
        angle = math.radians(angle_deg)
        assert (point.t, point.angle, point.theta, point.torque, point.normal_force,
                point.gap) == (t0 + t_s, angle, angle * arm, torque_mnm * 1e-3, force_n,
                               gap_mm * 1e-3)
    assert StreamBlock.of(list(block)) == block


if __name__ == "__main__":  # regenerate the fresh-contact reference (deliberately)
    data = json.loads(REFERENCE.read_text())
    data["shear"] = rehearsal_figures()
    REFERENCE.write_text(json.dumps(data, indent=1) + "\n")
