"""The APT wire format: message table, frame encode/decode and a resynchronising stream framer.

Only what the KDC101 rig uses is in the table. The framer is strict (known ids must have their
table form, addresses must be host <-> controller, channel words must be plausible) so garbage
is recognised and skipped; every failure it reports is an ``AptFramingError``.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum

from gelrig.instrument.core.errors import FramingError

HOST = 0x01
CONTROLLER = 0x50  # a stand-alone USB controller (K-Cube)
DATA_FLAG = 0x80
CHANNEL = 1
MAX_UNKNOWN_DATA = 255  # longest payload accepted for an id not in the table


class AptFramingError(FramingError):
    """Bytes that are not a valid APT frame (the framer has skipped past them)."""


class MsgId(IntEnum):
    """APT message ids used by the KDC101 rig (Thorlabs host-controller protocol)."""

    HW_REQ_INFO = 0x0005
    HW_GET_INFO = 0x0006
    HW_START_UPDATEMSGS = 0x0011
    HW_STOP_UPDATEMSGS = 0x0012
    HW_NO_FLASH_PROGRAMMING = 0x0018
    HW_RESPONSE = 0x0080
    HW_RICHRESPONSE = 0x0081
    MOD_SET_CHANENABLESTATE = 0x0210
    MOD_REQ_CHANENABLESTATE = 0x0211
    MOD_GET_CHANENABLESTATE = 0x0212
    MOD_IDENTIFY = 0x0223
    MOT_SET_POSCOUNTER = 0x0410
    MOT_REQ_POSCOUNTER = 0x0411
    MOT_GET_POSCOUNTER = 0x0412
    MOT_SET_VELPARAMS = 0x0413
    MOT_REQ_VELPARAMS = 0x0414
    MOT_GET_VELPARAMS = 0x0415
    MOT_SET_LIMSWITCHPARAMS = 0x0423
    MOT_REQ_LIMSWITCHPARAMS = 0x0424
    MOT_GET_LIMSWITCHPARAMS = 0x0425
    MOT_REQ_STATUSBITS = 0x0429
    MOT_GET_STATUSBITS = 0x042A
    MOT_SET_HOMEPARAMS = 0x0440
    MOT_REQ_HOMEPARAMS = 0x0441
    MOT_GET_HOMEPARAMS = 0x0442
    MOT_MOVE_HOME = 0x0443
    MOT_MOVE_HOMED = 0x0444
    MOT_MOVE_RELATIVE = 0x0448
    MOT_MOVE_ABSOLUTE = 0x0453
    MOT_MOVE_VELOCITY = 0x0457
    MOT_MOVE_COMPLETED = 0x0464
    MOT_MOVE_STOP = 0x0465
    MOT_MOVE_STOPPED = 0x0466
    MOT_REQ_DCSTATUSUPDATE = 0x0490
    MOT_GET_DCSTATUSUPDATE = 0x0491
    MOT_ACK_DCSTATUSUPDATE = 0x0492


@dataclass(frozen=True)
class Form:
    """Shape of a message: header only (``data_len is None``) or a fixed-length payload.

    ``short_form``: the header-only form is valid too (MOVE_RELATIVE / MOVE_ABSOLUTE without
    data use the stored move parameters, as the protocol document describes).
    """

    data_len: int | None
    has_channel: bool = False
    short_form: bool = False


_H = Form(None)


def _d(n: int, channel: bool = True) -> Form:
    return Form(n, channel)


#: The message table: id -> form. Payload layouts are in ``payloads``.
FORMS: dict[int, Form] = {
    MsgId.HW_REQ_INFO: _H,
    MsgId.HW_GET_INFO: _d(84, channel=False),
    MsgId.HW_START_UPDATEMSGS: _H,
    MsgId.HW_STOP_UPDATEMSGS: _H,
    MsgId.HW_NO_FLASH_PROGRAMMING: _H,
    MsgId.HW_RESPONSE: _H,
    MsgId.HW_RICHRESPONSE: _d(68, channel=False),
    MsgId.MOD_SET_CHANENABLESTATE: _H,
    MsgId.MOD_REQ_CHANENABLESTATE: _H,
    MsgId.MOD_GET_CHANENABLESTATE: _H,
    MsgId.MOD_IDENTIFY: _H,
    MsgId.MOT_SET_POSCOUNTER: _d(6),
    MsgId.MOT_REQ_POSCOUNTER: _H,
    MsgId.MOT_GET_POSCOUNTER: _d(6),
    MsgId.MOT_SET_VELPARAMS: _d(14),
    MsgId.MOT_REQ_VELPARAMS: _H,
    MsgId.MOT_GET_VELPARAMS: _d(14),
    MsgId.MOT_SET_LIMSWITCHPARAMS: _d(16),
    MsgId.MOT_REQ_LIMSWITCHPARAMS: _H,
    MsgId.MOT_GET_LIMSWITCHPARAMS: _d(16),
    MsgId.MOT_REQ_STATUSBITS: _H,
    MsgId.MOT_GET_STATUSBITS: _d(6),
    MsgId.MOT_SET_HOMEPARAMS: _d(14),
    MsgId.MOT_REQ_HOMEPARAMS: _H,
    MsgId.MOT_GET_HOMEPARAMS: _d(14),
    MsgId.MOT_MOVE_HOME: _H,
    MsgId.MOT_MOVE_HOMED: _H,
    MsgId.MOT_MOVE_RELATIVE: Form(6, True, short_form=True),
    MsgId.MOT_MOVE_ABSOLUTE: Form(6, True, short_form=True),
    MsgId.MOT_MOVE_VELOCITY: _H,
    MsgId.MOT_MOVE_COMPLETED: _d(14),
    MsgId.MOT_MOVE_STOP: _H,
    MsgId.MOT_MOVE_STOPPED: _d(14),
    MsgId.MOT_REQ_DCSTATUSUPDATE: _H,
    MsgId.MOT_GET_DCSTATUSUPDATE: _d(14),
    MsgId.MOT_ACK_DCSTATUSUPDATE: _H,
}

HEADER = struct.Struct("<HBBBB")
HEADER_DATA = struct.Struct("<HHBB")


def message_name(msg_id: int) -> str:
    """The table name of an id, or its hex for ids outside the table."""
    try:
        return MsgId(msg_id).name
    except ValueError:
        return f"0x{msg_id:04X}"


@dataclass(frozen=True)
class Message:
    """One APT message. ``data is None`` for the 6-byte header-only form."""

    msg_id: int
    param1: int = 0
    param2: int = 0
    data: bytes | None = None
    dest: int = CONTROLLER
    source: int = HOST

    @property
    def name(self) -> str:
        return message_name(self.msg_id)

    def __repr__(self) -> str:
        body = f"data={self.data.hex()}" if self.data is not None else (
            f"p1={self.param1}, p2={self.param2}")
        return f"Message({self.name}, {body}, {self.source:#04x}->{self.dest:#04x})"


def command(msg_id: int, param1: int = 0, param2: int = 0, *, to_host: bool = False) -> Message:
    """A header-only message, host -> controller unless ``to_host``."""
    dest, source = (HOST, CONTROLLER) if to_host else (CONTROLLER, HOST)
    return Message(msg_id, param1, param2, None, dest, source)


def data_message(msg_id: int, data: bytes, *, to_host: bool = False) -> Message:
    """A message with a payload, host -> controller unless ``to_host``."""
    dest, source = (HOST, CONTROLLER) if to_host else (CONTROLLER, HOST)
    return Message(msg_id, 0, 0, bytes(data), dest, source)


def encode(msg: Message) -> bytes:
    """Frame bytes of a message (the header's dest gets the 0x80 data flag when needed)."""
    if not 0 <= msg.msg_id <= 0xFFFF:
        raise AptFramingError(f"message id {msg.msg_id} does not fit 16 bits")
    if msg.data is None:
        return HEADER.pack(msg.msg_id, msg.param1 & 0xFF, msg.param2 & 0xFF, msg.dest, msg.source)
    if len(msg.data) > 0xFFFF:
        raise AptFramingError(f"payload of {len(msg.data)} bytes is too long")
    head = HEADER_DATA.pack(msg.msg_id, len(msg.data), msg.dest | DATA_FLAG, msg.source)
    return head + msg.data


def decode(frame: bytes) -> Message:
    """Exactly one message from ``frame``; AptFramingError if it is not exactly one."""
    framer = AptFramer()
    framer.feed(frame)
    msg = framer.next_message()
    if msg is None:
        raise AptFramingError(f"incomplete frame ({len(frame)} bytes): {frame.hex()}")
    if framer.pending:
        raise AptFramingError(f"{framer.pending} bytes after the frame")
    return msg


def _addresses_ok(dest: int, source: int) -> bool:
    return {dest, source} == {HOST, CONTROLLER}


def _check_header(buf: bytes | bytearray, start: int, forms: Mapping[int, Form] = FORMS
                  ) -> int | None:
    """Frame length if the 6 header bytes at ``start`` are plausible, else None."""
    msg_id, word, dest, source = HEADER_DATA.unpack_from(buf, start)
    form = forms.get(msg_id)
    if dest & DATA_FLAG:
        if not _addresses_ok(dest & 0x7F, source):
            return None
        if form is None:
            return 6 + word if 0 < word <= MAX_UNKNOWN_DATA else None
        return 6 + word if form.data_len == word else None
    if not _addresses_ok(dest, source):
        return None
    if form is not None and form.data_len is not None and not form.short_form:
        return None
    return 6


def _channel_ok(msg_id: int, data: bytes | bytearray, forms: Mapping[int, Form] = FORMS
                ) -> bool:
    form = forms.get(msg_id)
    if form is None or not form.has_channel:
        return True
    return data[1] == 0 and 1 <= data[0] <= 16


class AptFramer:
    """Splits a byte stream into messages, skipping garbage.

    ``feed`` bytes, then call ``next_message`` until it returns None (need more bytes). When
    the stream holds garbage, ``next_message`` drops it up to the next plausible header and
    raises one AptFramingError saying how much it dropped; the next call carries on.
    ``forms`` is the message table to check against (a simulator passes a larger one).
    """

    def __init__(self, forms: Mapping[int, Form] = FORMS) -> None:
        self.forms = forms
        self._buf = bytearray()
        self.discarded = 0  # total bytes skipped as garbage

    def feed(self, data: bytes) -> None:
        self._buf += data

    @property
    def pending(self) -> int:
        """Bytes buffered but not yet part of a returned message."""
        return len(self._buf)

    def clear(self) -> int:
        """Drop buffered bytes (a partial frame after a timeout); returns how many."""
        n = len(self._buf)
        self._buf.clear()
        return n

    def next_message(self) -> Message | None:
        buf = self._buf
        if len(buf) < 6:
            return None
        length = _check_header(buf, 0, self.forms)
        if length is not None:
            if len(buf) < length:
                return None
            msg_id = buf[0] | buf[1] << 8
            if length == 6:
                msg = Message(msg_id, buf[2], buf[3], None, buf[4], buf[5])
                del buf[:6]
                return msg
            data = bytes(buf[6:length])
            if _channel_ok(msg_id, data, self.forms):
                msg = Message(msg_id, 0, 0, data, buf[4] & 0x7F, buf[5])
                del buf[:length]
                return msg
        skip = self._resync_point()
        dropped = bytes(buf[:skip])
        del buf[:skip]
        self.discarded += skip
        shown = dropped[:16].hex() + ("..." if skip > 16 else "")
        raise AptFramingError(f"skipped {skip} bytes that are not an APT frame: {shown}")

    def _resync_point(self) -> int:
        """Index of the next plausible header after position 0 (or where a header may start)."""
        buf = self._buf
        for i in range(1, len(buf)):
            if len(buf) - i < 6:
                return i
            if _check_header(buf, i, self.forms) is not None:
                return i
        return len(buf)
