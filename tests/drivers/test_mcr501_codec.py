"""The MCR 501 command table and codec: framing, typed errors, round trips."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

import gelrig.drivers.mcr501.commands as commands
from gelrig.drivers.mcr501.codec import (
    InstrumentTrip,
    RequestError,
    UnknownCommand,
    decode_record,
    decode_reply,
    decode_request,
    encode,
    error_line,
)
from gelrig.drivers.mcr501.commands import COMMANDS, RECORD, split_key
from gelrig.instrument.core.errors import DeviceErrorReply, FramingError


def test_table_says_it_is_unconfirmed() -> None:
    doc = commands.__doc__ or ""
    assert "publishes no command reference" in doc
    assert "must be confirmed on the instrument" in doc


def test_table_holds_every_command_the_rig_uses() -> None:
    assert set(COMMANDS) == {
        "identify", "status", "zero_gap", "set_gap", "read_gap", "rotate", "rotate_for",
        "stop", "hold",
        "read_angle", "read_torque", "read_normal_force", "start_stream", "stop_stream",
        "read_stream",
    }  # fmt: skip
    for command in COMMANDS.values():
        assert split_key(command.request.encode(**_example(command.request))) is not None


def _example(message: commands.Message) -> dict[str, object]:
    if isinstance(message.shape, str):
        return {}
    values: dict[str, object] = {}
    for f in message.shape:
        values[f.name] = {"number": 1.25, "integer": 3, "hex": 0x2B}.get(
            f.kind, f.pattern.split("|")[0].replace("\\", "") if "|" in f.pattern else "x"
        )
    return values


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_requests_and_replies_round_trip(name: str) -> None:
    command = COMMANDS[name]
    line = command.request.encode(**_example(command.request))
    decoded, _ = decode_request(line)
    assert decoded is command
    reply = command.reply.encode(**_example(command.reply))
    assert decode_reply(command, reply) == (
        {} if isinstance(command.reply.shape, str) else command.reply.decode(reply)
    )


def test_literal_wire_forms() -> None:
    assert encode("identify") == "#VERS[?]"
    assert encode("rotate", direction="CW", rpm=0.5) == ":ROT[CW;5.000000e-01]"
    assert encode("set_gap", gap_mm=2.22) == ":GAP[2.2200]"
    assert encode("start_stream", interval_s=0.1) == ":RUN[0.1]"
    assert encode("stop") == ":STOP[]"
    with pytest.raises(KeyError, match="not in the MCR 501 command table"):
        encode("self_destruct")
    with pytest.raises(TypeError):
        encode("rotate", rpm=1.0)


def test_error_replies_raise_typed_errors() -> None:
    torque = COMMANDS["read_torque"]
    with pytest.raises(DeviceErrorReply) as err:
        decode_reply(torque, "#ERR[13;value out of range]")
    assert err.value.code == 13 and "value out of range" in str(err.value)
    with pytest.raises(UnknownCommand):
        decode_reply(torque, "#ERR[10;unknown command :TORQ]")
    with pytest.raises(InstrumentTrip) as trip:
        decode_reply(torque, "#ERR[32;]")
    assert trip.value.code == 32 and "torque over range" in str(trip.value)


@pytest.mark.parametrize(
    "line",
    [
        ":TORQ[0.1",  # closing bracket lost
        ":ANG[0.1]",  # the reply to another command
        ":TORQ[abc]",
        ":TORQ[0.1;0.2]",
        "",
        "#ERR[x;y]",
        ":TORQ[0.1]junk",
    ],
)
def test_malformed_replies_raise_framing_error(line: str) -> None:
    with pytest.raises(FramingError):
        decode_reply(COMMANDS["read_torque"], line)


def test_records() -> None:
    rec = RECORD.encode(t_s=1.5, angle_deg=-3.25, torque_mnm=0.1234567, force_n=0.09, gap_mm=2.22)
    assert rec == ":MEAS[1.5000;-3.2500000;0.123457;0.090000;2.2200]"
    assert decode_record(rec) == {
        "t_s": 1.5, "angle_deg": -3.25, "torque_mnm": 0.123457, "force_n": 0.09, "gap_mm": 2.22,
    }  # fmt: skip
    with pytest.raises(FramingError):
        decode_record(":MEAS[1;2;3;4]")


def test_request_decoding_on_the_instrument_side() -> None:
    command, values = decode_request(":ROT[CCW;8.4e-3]")
    assert command.name == "rotate" and values == {"direction": "CCW", "rpm": 8.4e-3}
    assert decode_request(":GAP[?]")[0].name == "read_gap"
    assert decode_request(":GAP[1.5]")[0].name == "set_gap"
    for line, code in ((":XYZ[]", 10), ("hello", 10), (":ROT[UP;1]", 11), (":GAP[]", 11)):
        with pytest.raises(RequestError) as err:
            decode_request(line)
        assert err.value.code == code


def test_error_line_keeps_the_framing() -> None:
    line = error_line(12, "send :GAPZ[] first; then [retry]\r\n")
    assert split_key(line) is not None
    with pytest.raises(DeviceErrorReply, match="send :GAPZ"):
        decode_reply(COMMANDS["set_gap"], line)


@given(
    st.floats(min_value=-1e4, max_value=1e4, allow_nan=False),
    st.floats(min_value=0, max_value=50),
)
def test_numbers_round_trip_within_the_format(angle: float, gap: float) -> None:
    rec = RECORD.encode(t_s=0.0, angle_deg=angle, torque_mnm=0.0, force_n=0.0, gap_mm=gap)
    values = decode_record(rec)
    assert values["angle_deg"] == pytest.approx(angle, abs=5e-8)
    assert values["gap_mm"] == pytest.approx(gap, abs=5e-5)
