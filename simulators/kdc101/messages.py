"""APT messages the simulated KDC101 answers beyond the driver's table (the driver needs none).

Parameter blocks (jog, general move, stored relative / absolute move, PID, potentiometer, MMI,
trigger I/O and trigger position) are stored as the payload bytes the host sent and returned
as they were, at the protocol document's length. Some SET messages are accepted at a shorter
length too, because a public client sends them so (pylablib packs the trigger blocks without
their reserved tail). Layouts follow the protocol document; see ADR 0101.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum


class SimMsgId(IntEnum):
    """Ids outside ``gelrig.drivers.kdc101.apt.MsgId`` that the simulator handles."""

    HW_DISCONNECT = 0x0002
    HUB_REQ_BAYUSED = 0x0065
    HUB_GET_BAYUSED = 0x0066
    MOT_SET_ENCCOUNTER = 0x0409
    MOT_REQ_ENCCOUNTER = 0x040A
    MOT_GET_ENCCOUNTER = 0x040B
    MOT_SET_JOGPARAMS = 0x0416
    MOT_REQ_JOGPARAMS = 0x0417
    MOT_GET_JOGPARAMS = 0x0418
    MOT_SET_GENMOVEPARAMS = 0x043A
    MOT_REQ_GENMOVEPARAMS = 0x043B
    MOT_GET_GENMOVEPARAMS = 0x043C
    MOT_SET_MOVERELPARAMS = 0x0445
    MOT_REQ_MOVERELPARAMS = 0x0446
    MOT_GET_MOVERELPARAMS = 0x0447
    MOT_SET_MOVEABSPARAMS = 0x0450
    MOT_REQ_MOVEABSPARAMS = 0x0451
    MOT_GET_MOVEABSPARAMS = 0x0452
    MOT_MOVE_JOG = 0x046A
    MOT_SET_DCPIDPARAMS = 0x04A0
    MOT_REQ_DCPIDPARAMS = 0x04A1
    MOT_GET_DCPIDPARAMS = 0x04A2
    MOT_SET_POTPARAMS = 0x04B0
    MOT_REQ_POTPARAMS = 0x04B1
    MOT_GET_POTPARAMS = 0x04B2
    MOT_SET_KCUBEMMIPARAMS = 0x0520
    MOT_REQ_KCUBEMMIPARAMS = 0x0521
    MOT_GET_KCUBEMMIPARAMS = 0x0522
    MOT_SET_KCUBETRIGIOCONFIG = 0x0523
    MOT_REQ_KCUBETRIGIOCONFIG = 0x0524
    MOT_GET_KCUBETRIGIOCONFIG = 0x0525
    MOT_SET_KCUBETRIGPOSPARAMS = 0x0526
    MOT_REQ_KCUBETRIGPOSPARAMS = 0x0527
    MOT_GET_KCUBETRIGPOSPARAMS = 0x0528


#: Header-only bay number of a stand-alone controller (HUB_GET_BAYUSED param1): -1.
BAY_STANDALONE = 0xFF

JOG_CONTINUOUS = 1
JOG_STEP = 2

JOG = struct.Struct("<HHllllH")  # chan, mode, step, min vel, accel, max vel, stop mode
CHAN_LONG = struct.Struct("<Hl")  # chan, one long (backlash, rel distance, abs position)
DCPID = struct.Struct("<HllllH")  # chan, P, I, D, integral limit, filter control
POT = struct.Struct("<HHlHlHlHl")  # chan, zero window, (velocity, window) x 3, velocity 4
MMI = struct.Struct("<HHllHllHHH6x")  # chan, JS mode, JS max vel, JS accel, dir sense,
# preset 1, preset 2, brightness, timeout, dim level, reserved
TRIGIO = struct.Struct("<HHHHH12x")  # chan, trig1 mode, trig1 polarity, trig2 mode, polarity
TRIGPOS = struct.Struct("<Hllllllll6x")  # chan, start/interval/pulses fw, the same bw,
# pulse width (us), cycles, reserved


@dataclass(frozen=True)
class Block:
    """A stored parameter block: its SET / REQ / GET ids and payload lengths."""

    name: str
    set_id: int
    req_id: int
    get_id: int
    length: int  # the protocol document's payload length (what GET replies carry)
    accepts: tuple[int, ...] = ()  # further lengths accepted on SET (padded with zeros)

    def lengths(self) -> tuple[int, ...]:
        return (self.length, *self.accepts)


BLOCKS = (
    Block("jog", SimMsgId.MOT_SET_JOGPARAMS, SimMsgId.MOT_REQ_JOGPARAMS,
          SimMsgId.MOT_GET_JOGPARAMS, JOG.size),
    Block("genmove", SimMsgId.MOT_SET_GENMOVEPARAMS, SimMsgId.MOT_REQ_GENMOVEPARAMS,
          SimMsgId.MOT_GET_GENMOVEPARAMS, CHAN_LONG.size),
    Block("moverel", SimMsgId.MOT_SET_MOVERELPARAMS, SimMsgId.MOT_REQ_MOVERELPARAMS,
          SimMsgId.MOT_GET_MOVERELPARAMS, CHAN_LONG.size),
    Block("moveabs", SimMsgId.MOT_SET_MOVEABSPARAMS, SimMsgId.MOT_REQ_MOVEABSPARAMS,
          SimMsgId.MOT_GET_MOVEABSPARAMS, CHAN_LONG.size),
    Block("dcpid", SimMsgId.MOT_SET_DCPIDPARAMS, SimMsgId.MOT_REQ_DCPIDPARAMS,
          SimMsgId.MOT_GET_DCPIDPARAMS, DCPID.size),
    Block("pot", SimMsgId.MOT_SET_POTPARAMS, SimMsgId.MOT_REQ_POTPARAMS,
          SimMsgId.MOT_GET_POTPARAMS, POT.size),
    Block("mmi", SimMsgId.MOT_SET_KCUBEMMIPARAMS, SimMsgId.MOT_REQ_KCUBEMMIPARAMS,
          SimMsgId.MOT_GET_KCUBEMMIPARAMS, MMI.size, accepts=(MMI.size - 6, MMI.size + 2)),
    Block("trigio", SimMsgId.MOT_SET_KCUBETRIGIOCONFIG, SimMsgId.MOT_REQ_KCUBETRIGIOCONFIG,
          SimMsgId.MOT_GET_KCUBETRIGIOCONFIG, TRIGIO.size, accepts=(TRIGIO.size - 12,)),
    Block("trigpos", SimMsgId.MOT_SET_KCUBETRIGPOSPARAMS, SimMsgId.MOT_REQ_KCUBETRIGPOSPARAMS,
          SimMsgId.MOT_GET_KCUBETRIGPOSPARAMS, TRIGPOS.size, accepts=(TRIGPOS.size - 6,)),
)
BLOCK_BY_SET = {b.set_id: b for b in BLOCKS}
BLOCK_BY_REQ = {b.req_id: b for b in BLOCKS}


@dataclass(frozen=True)
class JogParams:
    """MOT_SET/GET_JOGPARAMS in APT units (step in counts)."""

    mode: int
    step: int
    min_velocity: int
    acceleration: int
    max_velocity: int
    stop_mode: int

    @classmethod
    def unpack(cls, data: bytes) -> JogParams:
        _, mode, step, vmin, acc, vmax, stop = JOG.unpack(data)
        return cls(mode, step, vmin, acc, vmax, stop)

    def pack(self, channel: int = 1) -> bytes:
        return JOG.pack(channel, self.mode, self.step, self.min_velocity, self.acceleration,
                        self.max_velocity, self.stop_mode)


def chan_long(value: int, channel: int = 1) -> bytes:
    return CHAN_LONG.pack(channel, value)


def long_of(data: bytes) -> int:
    """The long of a ``<Hl`` block (backlash, stored relative distance or absolute position)."""
    return int(CHAN_LONG.unpack(data[:CHAN_LONG.size])[1])


def power_on_blocks(counts_per_m: float, apt_velocity: int, apt_accel: int) -> dict[str, bytes]:
    """Power-on contents of every block (values not from a real unit are UNVERIFIED)."""
    mm = round(1e-3 * counts_per_m)
    return {
        "jog": JogParams(JOG_STEP, round(0.05 * mm), 0, apt_accel, apt_velocity,
                         2).pack(),
        "genmove": chan_long(round(0.05 * mm)),
        "moverel": chan_long(round(0.1 * mm)),
        "moveabs": chan_long(0),
        "dcpid": DCPID.pack(1, 435, 195, 993, 195, 15),
        "pot": POT.pack(1, 20, apt_velocity // 10, 50, apt_velocity // 4, 80,
                        apt_velocity // 2, 100, apt_velocity),
        "mmi": MMI.pack(1, 1, apt_velocity, apt_accel, 0, 0, 0, 60, 10, 2),
        "trigio": TRIGIO.pack(1, 0, 1, 0, 1),
        "trigpos": TRIGPOS.pack(1, 0, 0, 1, 0, 0, 1, 100, 1),
    }
