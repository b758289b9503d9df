"""Payload layouts of the APT messages the rig uses, and the status-bit convention.

Each layout is a ``struct`` format plus a small dataclass; ``pack`` gives the payload bytes,
``unpack`` reads them back (AptFramingError on a wrong length). Which direction code and which
status bits mean *larger position counts* is the rig's ``direction`` setting, decoded in one
place, :class:`Directions` (ADR 0100; ADR 0004 keeps signed moves for everything else).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

from gelrig.drivers.kdc101.apt import CHANNEL, AptFramingError
from gelrig.instrument.contracts.stage import FORWARD_IS_NEGATIVE, FORWARD_IS_POSITIVE, StageStatus

# Status bits (MOT_GET_STATUSBITS / DC status update), named as in the protocol document.
# Which end each direction pair refers to is decided by ``Directions``, nowhere else.
LIMIT_FORWARD = 0x00000001  # "CW" hard limit
LIMIT_REVERSE = 0x00000002  # "CCW" hard limit
SOFT_LIMIT_FORWARD = 0x00000004
SOFT_LIMIT_REVERSE = 0x00000008
MOVING_FORWARD = 0x00000010
MOVING_REVERSE = 0x00000020
JOGGING_FORWARD = 0x00000040
JOGGING_REVERSE = 0x00000080
MOTOR_CONNECTED = 0x00000100
HOMING = 0x00000200
HOMED = 0x00000400
POSITION_ERROR = 0x00004000
ERROR = 0x40000000
ENABLED = 0x80000000
BUSY = MOVING_FORWARD | MOVING_REVERSE | JOGGING_FORWARD | JOGGING_REVERSE | HOMING

# MOT_MOVE_VELOCITY / MOT_MOVE_JOG / MOT_MOVE_STOP / MOD_SET_CHANENABLESTATE parameter values.
DIRECTION_FORWARD = 1  # the document's "forward"; see Directions for where it goes
DIRECTION_REVERSE = 2
STOP_IMMEDIATE = 1
STOP_PROFILED = 2
CHAN_ENABLED = 1
CHAN_DISABLED = 2


@dataclass(frozen=True)
class Directions:
    """The one table of what APT direction words mean on this controller (ADR 0100).

    ``sign`` is +1 for larger position counts, -1 for smaller. With ``forward_is_positive``
    False (a KDC101 as pylablib and thorlabs-apt-device encode it) direction code 1 and the
    "forward" bits 0x01 / 0x04 / 0x10 / 0x40 belong to *smaller* counts.
    """

    forward_is_positive: bool

    @classmethod
    def named(cls, name: str) -> Directions:
        """The convention of a ``StageConfig.direction`` / ``SimConfig.direction`` word."""
        if name not in (FORWARD_IS_NEGATIVE, FORWARD_IS_POSITIVE):
            raise ValueError(f"direction convention {name!r}: "
                             f"{FORWARD_IS_NEGATIVE} or {FORWARD_IS_POSITIVE}")
        return cls(name == FORWARD_IS_POSITIVE)

    def _forward(self, sign: int) -> bool:
        if sign not in (1, -1):
            raise ValueError(f"direction sign must be +1 or -1, got {sign}")
        return (sign > 0) == self.forward_is_positive

    def code(self, sign: int) -> int:
        """MOVE_VELOCITY / MOVE_JOG direction code for a move towards ``sign``."""
        return DIRECTION_FORWARD if self._forward(sign) else DIRECTION_REVERSE

    def sign(self, code: int) -> int:
        """Where a direction code goes (+1 larger counts); ValueError for codes other than 1/2."""
        if code not in (DIRECTION_FORWARD, DIRECTION_REVERSE):
            raise ValueError(f"direction code {code} (1 or 2)")
        forward = code == DIRECTION_FORWARD
        return 1 if forward == self.forward_is_positive else -1

    def moving_bit(self, sign: int) -> int:
        return MOVING_FORWARD if self._forward(sign) else MOVING_REVERSE

    def jogging_bit(self, sign: int) -> int:
        return JOGGING_FORWARD if self._forward(sign) else JOGGING_REVERSE

    def limit_bit(self, sign: int) -> int:
        """Hard-limit bit of the end towards ``sign``."""
        return LIMIT_FORWARD if self._forward(sign) else LIMIT_REVERSE

    def soft_limit_bit(self, sign: int) -> int:
        return SOFT_LIMIT_FORWARD if self._forward(sign) else SOFT_LIMIT_REVERSE


def decode_status(bits: int, directions: Directions | str = FORWARD_IS_NEGATIVE) -> StageStatus:
    """The rig's view of a KDC101 status word under a direction convention."""
    d = directions if isinstance(directions, Directions) else Directions.named(directions)
    return StageStatus(
        raw=bits,
        moving=bool(bits & (MOVING_FORWARD | MOVING_REVERSE | JOGGING_FORWARD | JOGGING_REVERSE)),
        homing=bool(bits & HOMING),
        homed=bool(bits & HOMED),
        enabled=bool(bits & ENABLED),
        motor_connected=bool(bits & MOTOR_CONNECTED),
        at_lower_limit=bool(bits & d.limit_bit(-1)),
        at_upper_limit=bool(bits & d.limit_bit(+1)),
        position_error=bool(bits & POSITION_ERROR),
        error=bool(bits & ERROR),
    )


def _unpack(fmt: struct.Struct, data: bytes, what: str) -> tuple[Any, ...]:
    if len(data) != fmt.size:
        raise AptFramingError(f"{what}: expected {fmt.size} payload bytes, got {len(data)}")
    return fmt.unpack(data)


_POSITION = struct.Struct("<Hl")
_STATUSBITS = struct.Struct("<HI")
_DCSTATUS = struct.Struct("<HlhhI")
_VELPARAMS = struct.Struct("<Hlll")
_HOMEPARAMS = struct.Struct("<HHHll")
_LIMSWITCH = struct.Struct("<HHHllH")
_RICH = struct.Struct("<HH64s")
_INFO = struct.Struct("<l8sH4s48s12sHHH")


def pack_position(counts: int, channel: int = CHANNEL) -> bytes:
    """MOVE_ABSOLUTE / MOVE_RELATIVE / SET|GET_POSCOUNTER payload."""
    return _POSITION.pack(channel, counts)


def unpack_position(data: bytes) -> tuple[int, int]:
    """(channel, counts)."""
    ch, counts = _unpack(_POSITION, data, "position")
    return ch, counts


def pack_statusbits(bits: int, channel: int = CHANNEL) -> bytes:
    return _STATUSBITS.pack(channel, bits)


def unpack_statusbits(data: bytes) -> tuple[int, int]:
    """(channel, status bits)."""
    ch, bits = _unpack(_STATUSBITS, data, "status bits")
    return ch, bits


@dataclass(frozen=True)
class DcStatus:
    """The 14-byte DC status block (status update, move completed, move stopped)."""

    position: int
    velocity: int
    current: int
    bits: int
    channel: int = CHANNEL

    def pack(self) -> bytes:
        return _DCSTATUS.pack(self.channel, self.position, self.velocity, self.current, self.bits)

    @classmethod
    def unpack(cls, data: bytes) -> DcStatus:
        ch, pos, vel, cur, bits = _unpack(_DCSTATUS, data, "DC status")
        return cls(pos, vel, cur, bits, ch)


@dataclass(frozen=True)
class VelParams:
    """Trapezoid parameters in APT units (min velocity is always 0 on the KDC101)."""

    min_velocity: int
    acceleration: int
    max_velocity: int
    channel: int = CHANNEL

    def pack(self) -> bytes:
        return _VELPARAMS.pack(self.channel, self.min_velocity, self.acceleration,
                               self.max_velocity)

    @classmethod
    def unpack(cls, data: bytes) -> VelParams:
        ch, vmin, acc, vmax = _unpack(_VELPARAMS, data, "velocity parameters")
        return cls(vmin, acc, vmax, ch)


@dataclass(frozen=True)
class HomeParams:
    """Homing: direction (1 fwd / 2 rev), limit switch (1 rev / 4 fwd), velocity, offset."""

    direction: int
    limit_switch: int
    velocity: int
    offset: int
    channel: int = CHANNEL

    def pack(self) -> bytes:
        return _HOMEPARAMS.pack(self.channel, self.direction, self.limit_switch, self.velocity,
                                self.offset)

    @classmethod
    def unpack(cls, data: bytes) -> HomeParams:
        ch, direction, switch, vel, offset = _unpack(_HOMEPARAMS, data, "home parameters")
        return cls(direction, switch, vel, offset, ch)


@dataclass(frozen=True)
class LimSwitchParams:
    """Limit-switch configuration: hardware switch kinds, soft limits (counts), soft mode."""

    cw_hard: int
    ccw_hard: int
    cw_soft: int
    ccw_soft: int
    mode: int
    channel: int = CHANNEL

    def pack(self) -> bytes:
        return _LIMSWITCH.pack(self.channel, self.cw_hard, self.ccw_hard, self.cw_soft,
                               self.ccw_soft, self.mode)

    @classmethod
    def unpack(cls, data: bytes) -> LimSwitchParams:
        ch, cw, ccw, cw_soft, ccw_soft, mode = _unpack(_LIMSWITCH, data, "limit switches")
        return cls(cw, ccw, cw_soft, ccw_soft, mode, ch)


@dataclass(frozen=True)
class RichResponse:
    """HW_RICHRESPONSE: the id of the offending message, an error code and a text."""

    msg_id: int
    code: int
    text: str

    def pack(self) -> bytes:
        return _RICH.pack(self.msg_id, self.code, self.text.encode("ascii", "replace")[:64])

    @classmethod
    def unpack(cls, data: bytes) -> RichResponse:
        msg_id, code, raw = _unpack(_RICH, data, "rich response")
        text = raw.split(b"\x00", 1)[0].decode("ascii", "replace").strip()
        return cls(msg_id, code, text)


@dataclass(frozen=True)
class HwInfo:
    """HW_GET_INFO: who the controller is. ``stage_id`` sits in the reserved block's end."""

    serial_number: int
    model: str
    hw_type: int
    firmware: tuple[int, int, int]  # (major, interim, minor)
    notes: str
    hw_version: int
    mod_state: int
    n_channels: int
    stage_id: int = 0

    def pack(self) -> bytes:
        major, interim, minor = self.firmware
        fw = bytes([minor, interim, major, 0])
        reserved = bytes(10) + struct.pack("<H", self.stage_id)
        return _INFO.pack(
            self.serial_number,
            self.model.encode("ascii")[:8],
            self.hw_type,
            fw,
            self.notes.encode("ascii", "replace")[:48],
            reserved,
            self.hw_version,
            self.mod_state,
            self.n_channels,
        )

    @classmethod
    def unpack(cls, data: bytes) -> HwInfo:
        sn, model, hw_type, fw, notes, reserved, hw_ver, mod_state, nch = _unpack(
            _INFO, data, "hardware info"
        )
        return cls(
            serial_number=sn,
            model=model.split(b"\x00", 1)[0].decode("ascii", "replace").strip(),
            hw_type=hw_type,
            firmware=(fw[2], fw[1], fw[0]),
            notes=notes.split(b"\x00", 1)[0].decode("ascii", "replace").strip(),
            hw_version=hw_ver,
            mod_state=mod_state,
            n_channels=nch,
            stage_id=struct.unpack("<H", reserved[10:12])[0],
        )
