"""The APT codec: known frames, every table message round-trips, random bytes only ever raise
the codec's own error, and the framer finds valid frames again after garbage."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gelrig.drivers.kdc101 import payloads as pl
from gelrig.drivers.kdc101.apt import (
    CONTROLLER,
    FORMS,
    HOST,
    AptFramer,
    AptFramingError,
    Message,
    MsgId,
    command,
    data_message,
    decode,
    encode,
)
from gelrig.instrument.core.errors import FramingError


def test_known_frames_match_the_protocol_document() -> None:
    assert encode(command(MsgId.HW_REQ_INFO)) == bytes.fromhex("050000005001")
    assert encode(command(MsgId.MOT_MOVE_STOP, 1, 2)) == bytes.fromhex("650401025001")
    move = data_message(MsgId.MOT_MOVE_ABSOLUTE, pl.pack_position(34555))
    assert encode(move) == bytes.fromhex("53040600d001" "0100" "fb860000")
    reply = decode(bytes.fromhex("120406008150" "0100" "feffffff"))
    assert reply.msg_id == MsgId.MOT_GET_POSCOUNTER and (reply.dest, reply.source) == (1, 0x50)
    assert pl.unpack_position(reply.data or b"") == (1, -2)


def test_payload_layouts_have_the_documented_sizes() -> None:
    assert len(pl.DcStatus(1, 2, 3, 4).pack()) == 14
    assert len(pl.VelParams(0, 1, 2).pack()) == 14
    assert len(pl.HomeParams(2, 1, 3, 4).pack()) == 14
    assert len(pl.LimSwitchParams(2, 2, 1, 0, 3).pack()) == 16
    assert len(pl.RichResponse(0x453, 4, "x").pack()) == 68
    info = pl.HwInfo(27001234, "KDC101", 16, (3, 0, 10), "notes", 1, 0, 1, 9)
    raw = info.pack()
    assert len(raw) == 84
    assert pl.HwInfo.unpack(raw) == info
    assert raw[76:78] == struct.pack("<H", 9)  # where pylablib looks for the stage id


def test_status_bits_decode() -> None:
    s = pl.decode_status(0x80000000 | 0x400 | 0x100 | 0x10 | 0x01)  # KDC101 default
    assert s.enabled and s.homed and s.motor_connected and s.moving and s.at_lower_limit
    assert not s.at_upper_limit and not s.homing and not s.error
    t = pl.decode_status(0x80000000 | 0x10 | 0x01, "forward_is_positive")
    assert t.at_upper_limit and not t.at_lower_limit
    assert pl.decode_status(0x200).busy and not pl.decode_status(0x200).moving


@pytest.mark.parametrize(
    ("name", "up_code", "up_moving", "low_limit"),
    [("forward_is_negative", 2, 0x20, 0x01), ("forward_is_positive", 1, 0x10, 0x02)],
)
def test_direction_conventions(name: str, up_code: int, up_moving: int, low_limit: int) -> None:
    d = pl.Directions.named(name)
    assert d.code(+1) == up_code and d.code(-1) == 3 - up_code
    assert d.sign(up_code) == 1 and d.sign(3 - up_code) == -1
    assert d.moving_bit(+1) == up_moving and d.jogging_bit(+1) == up_moving << 2
    assert d.limit_bit(-1) == low_limit and d.soft_limit_bit(-1) == low_limit << 2
    with pytest.raises(ValueError):
        d.sign(3)
    with pytest.raises(ValueError):
        pl.Directions.named("forwards")


def test_wrong_payload_length_is_a_framing_error() -> None:
    with pytest.raises(AptFramingError):
        pl.VelParams.unpack(b"\x01\x00")
    with pytest.raises(AptFramingError):
        decode(bytes.fromhex("1504" "0300" "8150" "010000"))  # GET_VELPARAMS is 14 bytes


def test_framer_resynchronises_after_garbage_and_truncation() -> None:
    good = encode(data_message(MsgId.MOT_GET_STATUSBITS, pl.pack_statusbits(0x400), to_host=True))
    framer = AptFramer()
    framer.feed(b"\x00\xff\x99garbage" + good[:3])  # garbage, then a frame cut short ...
    framer.feed(good)  # ... then a whole one
    got: list[Message] = []
    errors = 0
    for _ in range(50):
        try:
            msg = framer.next_message()
        except AptFramingError:
            errors += 1
            continue
        if msg is None:
            break
        got.append(msg)
    assert errors >= 1
    assert [m.msg_id for m in got] == [MsgId.MOT_GET_STATUSBITS]
    assert pl.unpack_statusbits(got[0].data or b"") == (1, 0x400)
    assert framer.pending == 0


def test_framer_waits_for_a_partial_frame() -> None:
    good = encode(data_message(MsgId.MOT_GET_POSCOUNTER, pl.pack_position(7), to_host=True))
    framer = AptFramer()
    framer.feed(good[:8])
    assert framer.next_message() is None
    framer.feed(good[8:])
    msg = framer.next_message()
    assert msg is not None and pl.unpack_position(msg.data or b"") == (1, 7)


def test_unknown_ids_with_a_valid_header_pass_through() -> None:
    msg = decode(encode(Message(0x7ABC, 1, 2, None, HOST, CONTROLLER)))
    assert (msg.msg_id, msg.param1, msg.param2, msg.name) == (0x7ABC, 1, 2, "0x7ABC")


def _messages() -> st.SearchStrategy[Message]:
    def build(msg_id: int, p1: int, p2: int, to_host: bool, payload: bytes) -> Message:
        form = FORMS[msg_id]
        dest, source = (HOST, CONTROLLER) if to_host else (CONTROLLER, HOST)
        if form.data_len is None:
            return Message(msg_id, p1, p2, None, dest, source)
        data = payload[: form.data_len].ljust(form.data_len, b"\x00")
        if form.has_channel:
            data = b"\x01\x00" + data[2:]
        return Message(msg_id, 0, 0, data, dest, source)

    return st.builds(
        build,
        st.sampled_from(sorted(FORMS)),
        st.integers(0, 255),
        st.integers(0, 255),
        st.booleans(),
        st.binary(min_size=0, max_size=84),
    )


@given(_messages())
def test_every_table_message_round_trips(msg: Message) -> None:
    frame = encode(msg)
    assert decode(frame) == msg
    assert len(frame) == 6 + (len(msg.data) if msg.data is not None else 0)


@given(st.lists(_messages(), min_size=1, max_size=8), st.integers(1, 7))
def test_a_stream_split_anywhere_gives_back_the_same_messages(msgs: list[Message], step: int
                                                              ) -> None:
    stream = b"".join(encode(m) for m in msgs)
    framer = AptFramer()
    out: list[Message] = []
    for i in range(0, len(stream), step):
        framer.feed(stream[i:i + step])
        while (m := framer.next_message()) is not None:
            out.append(m)
    assert out == msgs


@settings(max_examples=300)
@given(st.binary(max_size=400))
def test_random_bytes_only_raise_the_codecs_error(data: bytes) -> None:
    framer = AptFramer()
    framer.feed(data)
    for _ in range(len(data) + 2):
        try:
            if framer.next_message() is None and framer.pending < 6:
                break
        except AptFramingError as exc:
            assert isinstance(exc, FramingError)
    with contextlib.suppress(AptFramingError):  # the only error decode may raise
        decode(data)
