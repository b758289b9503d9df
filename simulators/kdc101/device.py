"""A simulated KDC101 K-Cube driving a Z825B actuator, answering APT bytes.

The state is computed lazily from ``clock.now()``: a command replaces the future of the
trajectory, and anything the controller says on its own (move completed, homed, status
updates every 100 ms) is produced, in time order, when a transport next asks for output. No
thread is needed in virtual time. Transports: ``protocol_kdc101sim`` (in-process pyserial URL)
and ``serve`` (TCP / pty server).

It speaks only when asked, plus the status stream and the move-completed / stopped / homed
notices; a request it does not know or rejects is logged (logger ``gelrig.simulators.kdc101``) and
recorded in ``rejected``, never answered with an error message (ADR 0101). Direction words
and bits follow ``SimConfig.direction`` (ADR 0100).

It survives any bytes: garbage is skipped up to the next plausible header, a message of the
wrong shape (a header-only form of a message that carries data, a payload of the wrong
length) or one whose handling fails is logged and dropped, and a partial frame that no byte
has followed for :data:`FRAME_GAP_S` of wall time is dropped when the next bytes arrive (a
UART receiver's inter-byte timeout), so garbage that looks like the head of a long frame
cannot swallow the next request.
"""

from __future__ import annotations

import bisect
import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gelrig.drivers.kdc101 import payloads as pl
from gelrig.drivers.kdc101.apt import (
    CHANNEL,
    CONTROLLER,
    FORMS,
    HOST,
    AptFramer,
    AptFramingError,
    Message,
    MsgId,
    command,
    data_message,
    encode,
)
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.motion import (  # the stage's kinematics (shared with the driver)
    Phase,
    Trajectory,
    clip_to_travel,
    plan_move,
    plan_stop,
    plan_velocity,
)
from gelrig.simulators.kdc101 import messages as sm
from gelrig.simulators.kdc101.config import SimConfig

#: Messages a simulator keeps for inspection (tests, fault reports): the latest ones.
KEPT_MESSAGES = 4096


def keep_latest(items: list[Any]) -> None:
    """Trim ``items`` to its latest KEPT_MESSAGES once it holds twice as many (amortised
    O(1))."""
    if len(items) > 2 * KEPT_MESSAGES:
        del items[:-KEPT_MESSAGES]


log = logging.getLogger("gelrig.simulators.kdc101")

T_UNIT = 2048 / 6e6  # KDC101 velocity/acceleration time unit (s)
UPDATE_PERIOD_S = 0.1
MAX_UNACKED_UPDATES = 50
#: Wall seconds after which a partial frame no byte has followed is dropped.
FRAME_GAP_S = 0.25


class KDC101Simulator:
    """The controller and actuator. Transports call ``receive``, ``read`` and friends.

    Positions inside are metres of extension from the home limit switch (``position_at``);
    the encoder counter is zeroed at power-on and at the end of homing.
    """

    def __init__(self, clock: Clock, config: SimConfig | None = None):
        self.clock = clock
        self.config = config or SimConfig()
        c = self.config
        now = clock.now()
        self._lock = threading.RLock()
        self.directions = pl.Directions.named(c.direction)
        self._framer = AptFramer()
        self._out = bytearray()
        #: bytes said but still on their way to the host: (arrival time, bytes), in order
        self._in_flight: list[tuple[float, bytes]] = []
        self.kinematics = Trajectory(c.start_position_m, now)
        self._origin_m = c.start_position_m
        self._origins = [(now, c.start_position_m)]  # (from time, counter origin) history
        self.enabled = True
        self.homed = False
        self._v_max = c.max_velocity_m_s
        self._accel = c.acceleration_m_s2
        self._home_params = pl.HomeParams(2, 1, self._apt_velocity(c.home_velocity_m_s),
                                          round(c.home_offset_m * c.counts_per_m))
        self._lim_params = pl.LimSwitchParams(2, 2, 0, 0, 1)
        self._blocks = sm.power_on_blocks(c.counts_per_m, self._apt_velocity(c.max_velocity_m_s),
                                          self._apt_accel(c.acceleration_m_s2))
        # The motion in progress: its kind, end time, direction and the event at its end.
        self._motion: str | None = None
        self._motion_end = math.inf
        self._motion_dir = 0
        self._end_event: int | None = None
        self._homing_origin: float | None = None
        # Status update stream.
        self._updates = False
        self._next_update = math.inf
        self.unacked_updates = 0
        # Fault injection and bookkeeping.
        self.muted = False
        self.connected = True
        #: the latest requests received, oldest first (at most 2 x KEPT_MESSAGES: a simulator
        #: that runs for days does not keep every message it ever got)
        self.received: list[Message] = []
        self.rejected: list[tuple[Message, str]] = []  # requests logged instead of answered
        self.garbage_received = 0
        self.stale_dropped = 0  # bytes of partial frames dropped after FRAME_GAP_S
        #: wall clock of the inter-byte timeout (not the simulated clock: a virtual clock
        #: stands still between a client's writes); replaceable in tests
        self.wall: Callable[[], float] = time.monotonic
        self._last_rx = self.wall()

    # ---- unit conversions -------------------------------------------------------------
    def _apt_velocity(self, v_m_s: float) -> int:
        return round(v_m_s * self.config.counts_per_m * T_UNIT * 65536)

    def _apt_accel(self, a_m_s2: float) -> int:
        return round(a_m_s2 * self.config.counts_per_m * T_UNIT * T_UNIT * 65536)

    def _velocity_from_apt(self, units: int) -> float:
        return units / (T_UNIT * 65536) / self.config.counts_per_m

    def _accel_from_apt(self, units: int) -> float:
        return units / (T_UNIT * T_UNIT * 65536) / self.config.counts_per_m

    # ---- the observable state (pure functions of time) --------------------------------
    def position_at(self, t: float) -> float:
        """Actuator extension (m) from the home switch at time ``t``: the plate's position."""
        with self._lock:
            return self.kinematics.position_at(t)

    def positions_at(self, ts: NDArray[np.float64]) -> NDArray[np.float64]:
        """``position_at`` for an array of times (a whole acquisition block in one call)."""
        with self._lock:
            return self.kinematics.positions_at(np.asarray(ts, dtype=float))

    def velocity_at(self, t: float) -> float:
        """Actuator velocity (m/s) at time ``t``."""
        with self._lock:
            return self.kinematics.velocity_at(t)

    def axis_position_at(self, t: float) -> float:
        """The stage position (m) at ``t`` in the axis the driver reports: extension minus
        the encoder counter's origin at that time (unquantized; changes frame when homing
        completes). Pure for any ``t`` up to now."""
        with self._lock:
            self._advance(self.clock.now())
            return self.kinematics.position_at(t) - self._origin_at(t)

    def axis_positions_at(self, ts: NDArray[np.float64]) -> NDArray[np.float64]:
        """``axis_position_at`` for an array of times (an acquisition block in one call)."""
        with self._lock:
            self._advance(self.clock.now())
            ts = np.asarray(ts, dtype=float)
            starts = np.array([t for t, _ in self._origins])
            values = np.array([o for _, o in self._origins])
            idx = np.clip(np.searchsorted(starts, ts, side="right") - 1, 0, None)
            out: NDArray[np.float64] = self.kinematics.positions_at(ts) - values[idx]
            return out

    def _origin_at(self, t: float) -> float:
        i = bisect.bisect_right([s for s, _ in self._origins], t) - 1
        return self._origins[max(i, 0)][1]

    def _set_origin(self, t: float, origin: float) -> None:
        self._origin_m = origin
        self._origins = [o for o in self._origins if o[0] < t] + [(t, origin)]

    @property
    def counter_origin_m(self) -> float:
        """Extension at which the encoder counter reads 0 (moves when homing completes)."""
        return self._origin_m

    def counts_at(self, t: float) -> int:
        """The encoder counter at ``t``: quantized position relative to the counter origin."""
        return round((self.kinematics.position_at(t) - self._origin_m) * self.config.counts_per_m)

    def status_bits_at(self, t: float) -> int:
        x = self.kinematics.position_at(t)
        v = self.kinematics.velocity_at(t)
        bits = pl.MOTOR_CONNECTED
        if self.enabled:
            bits |= pl.ENABLED
        if self.homed:
            bits |= pl.HOMED
        d = self.directions
        if self._motion is not None and t < self._motion_end:
            direction = (v > 0) - (v < 0) or self._motion_dir or -1
            bits |= d.moving_bit(direction)
            if self._motion == "jog":
                bits |= d.jogging_bit(direction)
            if self._motion == "home":
                bits |= pl.HOMING
        soft = self.soft_limits_m()
        if soft is not None and x <= soft[0] + 1e-9:
            bits |= d.soft_limit_bit(-1)
        if soft is not None and x >= soft[1] - 1e-9:
            bits |= d.soft_limit_bit(+1)
        if x <= 1e-9:
            bits |= d.limit_bit(-1)
        if x >= self.config.travel_m - 1e-9:
            bits |= d.limit_bit(+1)
        return bits

    def _dc_status(self, t: float) -> pl.DcStatus:
        v_units = self._apt_velocity(abs(self.kinematics.velocity_at(t))) >> 16
        return pl.DcStatus(self.counts_at(t), min(v_units, 0x7FFF), 0, self.status_bits_at(t))

    # ---- time: spontaneous messages ---------------------------------------------------
    def next_event_time(self) -> float:
        """When the controller will next say something by itself (inf: never)."""
        with self._lock:
            t_upd = self._next_update if self._updates else math.inf
            t_end = self._motion_end if self._motion is not None else math.inf
            t_out = self._in_flight[0][0] if self._in_flight else math.inf
            return min(t_upd, t_end, t_out)

    def _advance(self, now: float) -> None:
        """Produce, in time order, everything due up to ``now``."""
        while True:
            t_upd = self._next_update if self._updates else math.inf
            t_end = self._motion_end if self._motion is not None else math.inf
            t = min(t_upd, t_end)
            if t > now:
                self._deliver(now)
                return
            if t_end <= t_upd:
                self._finish_motion(t_end)
            else:
                self._send_update(t_upd)

    def _finish_motion(self, t: float) -> None:
        if self._motion == "home" and self._homing_origin is not None:
            self.homed = True
            self._set_origin(t, self._homing_origin)
            self._homing_origin = None
        event = self._end_event
        self._motion, self._motion_end, self._end_event = None, math.inf, None
        if event == MsgId.MOT_MOVE_HOMED:
            self._emit(command(event, CHANNEL, 0, to_host=True), t)
        elif event is not None:
            self._emit(data_message(event, self._dc_status(t).pack(), to_host=True), t)

    def _send_update(self, t: float) -> None:
        self._emit(data_message(MsgId.MOT_GET_DCSTATUSUPDATE, self._dc_status(t).pack(),
                                to_host=True), t)
        self.unacked_updates += 1
        self._next_update = t + self.config.update_period_s
        if self.unacked_updates >= MAX_UNACKED_UPDATES:
            self._updates = False  # the host stopped acknowledging: the stream stops

    def _emit(self, msg: Message, t: float | None = None) -> None:
        """Say ``msg`` at ``t`` (default now): it reaches the host ``reply_latency`` later."""
        if self.muted:
            return
        latency = self.config.reply_latency
        if latency <= 0:
            self._out += encode(msg)
            return
        at = (self.clock.now() if t is None else t) + latency
        if self._in_flight and at < self._in_flight[-1][0]:
            at = self._in_flight[-1][0]  # the link keeps the order
        self._in_flight.append((at, encode(msg)))

    def _deliver(self, now: float) -> None:
        """Move what has reached the host by ``now`` to the host's side of the link."""
        while self._in_flight and self._in_flight[0][0] <= now:
            self._out += self._in_flight.pop(0)[1]

    # ---- the transport side -----------------------------------------------------------
    def receive(self, data: bytes) -> None:
        """Bytes from the host, arriving now."""
        with self._lock:
            now = self.clock.now()
            self._advance(now)
            wall = self.wall()
            if self._framer.pending and wall - self._last_rx > FRAME_GAP_S:
                dropped = self._framer.clear()
                self.stale_dropped += dropped
                log.warning("KDC101 %d dropped %d bytes of a partial frame no byte followed "
                            "for %.2f s", self.config.serial_number, dropped,
                            wall - self._last_rx)
            self._last_rx = wall
            self._framer.feed(data)
            while True:
                try:
                    msg = self._framer.next_message()
                except AptFramingError as exc:
                    self.garbage_received += 1
                    log.warning("KDC101 %d: %s", self.config.serial_number, exc)
                    continue
                if msg is None:
                    return
                self.received.append(msg)
                keep_latest(self.received)
                try:
                    self._handle(msg, now)
                except Exception as exc:  # a payload the handler cannot take: drop it
                    log.debug("handling %r failed", msg, exc_info=True)
                    self._reject(msg, f"malformed: {type(exc).__name__}: {exc}")

    def read(self, max_bytes: int | None = None) -> bytes:
        """Bytes the controller has sent up to now (at most ``max_bytes``)."""
        with self._lock:
            self._advance(self.clock.now())
            n = len(self._out) if max_bytes is None else min(max_bytes, len(self._out))
            out = bytes(self._out[:n])
            del self._out[:n]
            return out

    def out_waiting(self) -> int:
        """How many bytes are ready to read now."""
        with self._lock:
            self._advance(self.clock.now())
            return len(self._out)

    def discard_output(self) -> None:
        """Forget unread output (the host purged its receive buffer)."""
        with self._lock:
            self._advance(self.clock.now())
            self._out.clear()

    # ---- fault injection --------------------------------------------------------------
    def inject(self, data: bytes) -> None:
        """Put raw bytes on the wire to the host now (garbage, truncated frames...)."""
        with self._lock:
            self._advance(self.clock.now())
            self._out += data

    def mute(self, muted: bool = True) -> None:
        """Stop (or resume) sending anything; commands are still obeyed."""
        with self._lock:
            self._advance(self.clock.now())
            self.muted = muted

    def disconnect(self) -> None:
        """Drop the link: transports raise on the next read or write."""
        with self._lock:
            self.connected = False

    def reconnect(self) -> None:
        """The link is back (a new client): a partial frame of the last one is forgotten."""
        with self._lock:
            self.connected = True
            self._framer.clear()

    # ---- message handling -------------------------------------------------------------
    def _reject(self, msg: Message, why: str) -> None:
        """Log a request the controller does not obey; nothing goes on the wire."""
        self.rejected.append((msg, why))
        keep_latest(self.rejected)
        log.warning("KDC101 %d ignored %r: %s", self.config.serial_number, msg, why)

    def inject_error(self, msg_id: int, code: int, text: str, rich: bool = True) -> None:
        """Fault hook: put a HW_RICHRESPONSE (or bare HW_RESPONSE) on the wire now."""
        if rich:
            data = pl.RichResponse(msg_id, code, text).pack()
            self.inject(encode(data_message(MsgId.HW_RICHRESPONSE, data, to_host=True)))
        else:
            self.inject(encode(command(MsgId.HW_RESPONSE, code & 0xFF, 0, to_host=True)))

    def _reply(self, msg_id: int, data: bytes) -> None:
        self._emit(data_message(msg_id, data, to_host=True))

    def _handle(self, msg: Message, now: float) -> None:
        if msg.dest != CONTROLLER or msg.source != HOST:
            return
        handler = _HANDLERS.get(msg.msg_id)
        if handler is None:
            self._reject(msg, f"unknown message id 0x{msg.msg_id:04X}")
            return
        shape = _shape_error(msg)
        if shape:
            self._reject(msg, shape)
            return
        form = FORMS.get(msg.msg_id)
        with_channel = (form is not None and form.has_channel) or msg.msg_id in _DATA_WITH_CHANNEL
        channel = msg.data[0] | msg.data[1] << 8 if msg.data and with_channel else None
        if msg.data is None and msg.msg_id in _CHANNEL_IN_PARAM1:
            channel = msg.param1
        if channel is not None and channel != CHANNEL:
            self._reject(msg, f"no channel {channel} (KDC101 has 1)")
            return
        handler(self, msg, now)

    def _on_info(self, msg: Message, now: float) -> None:
        c = self.config
        info = pl.HwInfo(c.serial_number, "KDC101", 16, c.firmware, "APT DC Motor Controller",
                         1, 0, 1, c.stage_id)
        self._reply(MsgId.HW_GET_INFO, info.pack())

    def _on_start_updates(self, msg: Message, now: float) -> None:
        self._updates = True
        self.unacked_updates = 0
        self._next_update = now + self.config.update_period_s

    def _on_stop_updates(self, msg: Message, now: float) -> None:
        self._updates = False

    def _on_ack(self, msg: Message, now: float) -> None:
        self.unacked_updates = 0

    def _on_nothing(self, msg: Message, now: float) -> None:
        return

    def _on_set_enable(self, msg: Message, now: float) -> None:
        if msg.param2 not in (pl.CHAN_ENABLED, pl.CHAN_DISABLED):
            self._reject(msg, f"enable state {msg.param2} (1 or 2)")
            return
        self.enabled = msg.param2 == pl.CHAN_ENABLED
        if not self.enabled and self._motion is not None:
            self._start(now, plan_stop(now, self._x(now), 0.0, 1.0, immediate=True), "stop",
                        0, MsgId.MOT_MOVE_STOPPED)

    def _on_req_enable(self, msg: Message, now: float) -> None:
        state = pl.CHAN_ENABLED if self.enabled else pl.CHAN_DISABLED
        self._emit(command(MsgId.MOD_GET_CHANENABLESTATE, CHANNEL, state, to_host=True))

    def _on_set_poscounter(self, msg: Message, now: float) -> None:
        _, counts = pl.unpack_position(msg.data or b"")
        self._set_origin(now, self._x(now) - counts / self.config.counts_per_m)

    def _on_req_poscounter(self, msg: Message, now: float) -> None:
        self._reply(MsgId.MOT_GET_POSCOUNTER, pl.pack_position(self.counts_at(now)))

    def _on_set_velparams(self, msg: Message, now: float) -> None:
        p = pl.VelParams.unpack(msg.data or b"")
        v, a = self._velocity_from_apt(p.max_velocity), self._accel_from_apt(p.acceleration)
        c, tol = self.config, 1 + 1e-6
        if not (0 < v <= c.velocity_cap_m_s * tol and 0 < a <= c.accel_cap_m_s2 * tol):
            self._reject(msg, f"velocity {v * 1e3:.3f} mm/s or accel {a * 1e3:.3f} mm/s2 "
                         "out of range")
            return
        self._v_max, self._accel = v, a

    def _on_req_velparams(self, msg: Message, now: float) -> None:
        p = pl.VelParams(0, self._apt_accel(self._accel), self._apt_velocity(self._v_max))
        self._reply(MsgId.MOT_GET_VELPARAMS, p.pack())

    def _on_set_homeparams(self, msg: Message, now: float) -> None:
        p = pl.HomeParams.unpack(msg.data or b"")
        if p.velocity <= 0 or self._velocity_from_apt(p.velocity) > self.config.velocity_cap_m_s:
            self._reject(msg, "home velocity out of range")
            return
        self._home_params = p

    def _on_req_homeparams(self, msg: Message, now: float) -> None:
        self._reply(MsgId.MOT_GET_HOMEPARAMS, self._home_params.pack())

    def _on_set_limswitch(self, msg: Message, now: float) -> None:
        self._lim_params = pl.LimSwitchParams.unpack(msg.data or b"")

    def _on_req_limswitch(self, msg: Message, now: float) -> None:
        self._reply(MsgId.MOT_GET_LIMSWITCHPARAMS, self._lim_params.pack())

    def _on_req_statusbits(self, msg: Message, now: float) -> None:
        self._reply(MsgId.MOT_GET_STATUSBITS, pl.pack_statusbits(self.status_bits_at(now)))

    def _on_req_dcstatus(self, msg: Message, now: float) -> None:
        self._reply(MsgId.MOT_GET_DCSTATUSUPDATE, self._dc_status(now).pack())

    # ---- motion -----------------------------------------------------------------------
    def _x(self, t: float) -> float:
        return self.kinematics.position_at(t)

    def _require_enabled(self, msg: Message) -> bool:
        if not self.enabled:
            self._reject(msg, "channel disabled: enable it before moving")
        return self.enabled

    def soft_limits_m(self) -> tuple[float, float] | None:
        """The controller's software limits as extensions, when active (homed, mode 2/3)."""
        p = self._lim_params
        if not self.homed or p.mode not in (2, 3) or p.ccw_soft == p.cw_soft:
            return None
        # Which field holds which end is UNVERIFIED (ADR 0100): the pair is read unordered.
        lo, hi = sorted((p.ccw_soft, p.cw_soft))
        cpm = self.config.counts_per_m
        return self._origin_m + lo / cpm, self._origin_m + hi / cpm

    def _start(self, now: float, phases: list[Phase], kind: str, direction: int,
               end_event: int | None) -> None:
        lo, hi = 0.0, self.config.travel_m
        soft = self.soft_limits_m() if kind != "home" else None
        if soft is not None:
            lo, hi = max(lo, soft[0]), min(hi, soft[1])
        phases, t_hit = clip_to_travel(phases, lo, hi)
        self.kinematics.replace_from(now, phases)
        end = self.kinematics.end_time
        if kind in ("velocity", "jog") and end_event is None and t_hit is None:
            end = math.inf  # runs until stopped
        if t_hit is not None:
            end_event = MsgId.MOT_MOVE_STOPPED  # stopped by a limit switch
            if kind == "home":
                end_event = None
        self._motion, self._motion_end = kind, end
        self._motion_dir, self._end_event = direction, end_event

    def _move_to_m(self, now: float, target: float) -> None:
        x, v = self._x(now), self.kinematics.velocity_at(now)
        phases = plan_move(now, x, v, target, self._v_max, self._accel)
        direction = (target > x) - (target < x)
        self._start(now, phases, "move", direction, MsgId.MOT_MOVE_COMPLETED)

    def _on_move_absolute(self, msg: Message, now: float) -> None:
        if self._require_enabled(msg):
            if msg.data is None:  # the short form: the stored MOVEABSPARAMS position
                counts = sm.long_of(self._blocks["moveabs"])
            else:
                _, counts = pl.unpack_position(msg.data)
            self._move_to_m(now, self._origin_m + counts / self.config.counts_per_m)

    def _on_move_relative(self, msg: Message, now: float) -> None:
        if self._require_enabled(msg):
            if msg.data is None:  # the short form: the stored MOVERELPARAMS distance
                counts = sm.long_of(self._blocks["moverel"])
            else:
                _, counts = pl.unpack_position(msg.data)
            # Relative to the current target if moving, as the controller does.
            base = self._x(max(now, self.kinematics.end_time)) if self._motion == "move" \
                else self._x(now)
            self._move_to_m(now, base + counts / self.config.counts_per_m)

    def _on_move_velocity(self, msg: Message, now: float) -> None:
        if msg.param2 not in (pl.DIRECTION_FORWARD, pl.DIRECTION_REVERSE):
            self._reject(msg, f"direction {msg.param2} (1 or 2)")
            return
        if self._require_enabled(msg):
            direction = self.directions.sign(msg.param2)
            x, v = self._x(now), self.kinematics.velocity_at(now)
            phases = plan_velocity(now, x, v, direction, self._v_max, self._accel)
            self._start(now, phases, "velocity", direction, None)

    def _on_move_stop(self, msg: Message, now: float) -> None:
        if msg.param2 not in (pl.STOP_IMMEDIATE, pl.STOP_PROFILED):
            self._reject(msg, f"stop mode {msg.param2} (1 or 2)")
            return
        x, v = self._x(now), self.kinematics.velocity_at(now)
        phases = plan_stop(now, x, v, self._accel, immediate=msg.param2 == pl.STOP_IMMEDIATE)
        self._homing_origin = None
        self._start(now, phases, "stop", (v > 0) - (v < 0), MsgId.MOT_MOVE_STOPPED)

    def _on_move_home(self, msg: Message, now: float) -> None:
        if not self._require_enabled(msg):
            return
        c = self.config
        v_home = self._velocity_from_apt(self._home_params.velocity)
        offset = self._home_params.offset / c.counts_per_m
        x, v = self._x(now), self.kinematics.velocity_at(now)
        to_switch = plan_move(now, x, v, 0.0, v_home, self._accel)
        rest = to_switch[-1]
        back_out = plan_move(rest.t0, 0.0, 0.0, offset, v_home, self._accel)
        self._homing_origin = offset
        self.homed = False  # a new homing: HOMED clears now and sets when it completes
        self._start(now, to_switch[:-1] + back_out, "home", -1, MsgId.MOT_MOVE_HOMED)

    def _on_move_jog(self, msg: Message, now: float) -> None:
        if msg.param2 not in (pl.DIRECTION_FORWARD, pl.DIRECTION_REVERSE):
            self._reject(msg, f"jog direction {msg.param2} (1 or 2)")
            return
        if not self._require_enabled(msg):
            return
        direction = self.directions.sign(msg.param2)
        jog = sm.JogParams.unpack(self._blocks["jog"])
        v_jog = self._velocity_from_apt(jog.max_velocity)
        a_jog = self._accel_from_apt(jog.acceleration)
        x, v = self._x(now), self.kinematics.velocity_at(now)
        if jog.mode == sm.JOG_CONTINUOUS:  # runs until MOT_MOVE_STOP (or a limit)
            self._start(now, plan_velocity(now, x, v, direction, v_jog, a_jog), "jog",
                        direction, None)
            return
        base = self._x(max(now, self.kinematics.end_time)) if self._motion == "jog" else x
        target = base + direction * jog.step / self.config.counts_per_m
        self._start(now, plan_move(now, x, v, target, v_jog, a_jog), "jog", direction,
                    MsgId.MOT_MOVE_COMPLETED)

    # ---- parameter blocks and the rest of the KDC101 set ------------------------------
    def _on_set_block(self, msg: Message, now: float) -> None:
        block = sm.BLOCK_BY_SET[msg.msg_id]  # its length checked by _shape_error
        data = (msg.data or b"").ljust(block.length, b"\0")[:block.length]
        if block.name == "jog":
            jog = sm.JogParams.unpack(data)
            v = self._velocity_from_apt(jog.max_velocity)
            a = self._accel_from_apt(jog.acceleration)
            c, tol = self.config, 1 + 1e-6
            if (jog.mode not in (sm.JOG_CONTINUOUS, sm.JOG_STEP)
                    or jog.stop_mode not in (pl.STOP_IMMEDIATE, pl.STOP_PROFILED)
                    or not 0 < v <= c.velocity_cap_m_s * tol
                    or not 0 < a <= c.accel_cap_m_s2 * tol):
                self._reject(msg, f"jog parameters out of range: {jog}")
                return
        self._blocks[block.name] = data

    def _on_req_block(self, msg: Message, now: float) -> None:
        block = sm.BLOCK_BY_REQ[msg.msg_id]
        self._reply(block.get_id, self._blocks[block.name])

    def _on_req_enccounter(self, msg: Message, now: float) -> None:
        self._reply(sm.SimMsgId.MOT_GET_ENCCOUNTER, pl.pack_position(self.counts_at(now)))

    def _on_req_bayused(self, msg: Message, now: float) -> None:
        self._emit(command(sm.SimMsgId.HUB_GET_BAYUSED, sm.BAY_STANDALONE, 0, to_host=True))


_HANDLERS: dict[int, Callable[[KDC101Simulator, Message, float], None]] = {
    MsgId.HW_REQ_INFO: KDC101Simulator._on_info,
    MsgId.HW_START_UPDATEMSGS: KDC101Simulator._on_start_updates,
    MsgId.HW_STOP_UPDATEMSGS: KDC101Simulator._on_stop_updates,
    MsgId.HW_NO_FLASH_PROGRAMMING: KDC101Simulator._on_nothing,
    MsgId.MOD_IDENTIFY: KDC101Simulator._on_nothing,
    MsgId.MOD_SET_CHANENABLESTATE: KDC101Simulator._on_set_enable,
    MsgId.MOD_REQ_CHANENABLESTATE: KDC101Simulator._on_req_enable,
    MsgId.MOT_SET_POSCOUNTER: KDC101Simulator._on_set_poscounter,
    MsgId.MOT_REQ_POSCOUNTER: KDC101Simulator._on_req_poscounter,
    MsgId.MOT_SET_VELPARAMS: KDC101Simulator._on_set_velparams,
    MsgId.MOT_REQ_VELPARAMS: KDC101Simulator._on_req_velparams,
    MsgId.MOT_SET_HOMEPARAMS: KDC101Simulator._on_set_homeparams,
    MsgId.MOT_REQ_HOMEPARAMS: KDC101Simulator._on_req_homeparams,
    MsgId.MOT_SET_LIMSWITCHPARAMS: KDC101Simulator._on_set_limswitch,
    MsgId.MOT_REQ_LIMSWITCHPARAMS: KDC101Simulator._on_req_limswitch,
    MsgId.MOT_REQ_STATUSBITS: KDC101Simulator._on_req_statusbits,
    MsgId.MOT_REQ_DCSTATUSUPDATE: KDC101Simulator._on_req_dcstatus,
    MsgId.MOT_ACK_DCSTATUSUPDATE: KDC101Simulator._on_ack,
    MsgId.MOT_MOVE_ABSOLUTE: KDC101Simulator._on_move_absolute,
    MsgId.MOT_MOVE_RELATIVE: KDC101Simulator._on_move_relative,
    MsgId.MOT_MOVE_VELOCITY: KDC101Simulator._on_move_velocity,
    MsgId.MOT_MOVE_STOP: KDC101Simulator._on_move_stop,
    MsgId.MOT_MOVE_HOME: KDC101Simulator._on_move_home,
    sm.SimMsgId.HW_DISCONNECT: KDC101Simulator._on_nothing,
    sm.SimMsgId.HUB_REQ_BAYUSED: KDC101Simulator._on_req_bayused,
    # A DC servo's position counter is its encoder counter.
    sm.SimMsgId.MOT_SET_ENCCOUNTER: KDC101Simulator._on_set_poscounter,
    sm.SimMsgId.MOT_REQ_ENCCOUNTER: KDC101Simulator._on_req_enccounter,
    sm.SimMsgId.MOT_MOVE_JOG: KDC101Simulator._on_move_jog,
    **{b.set_id: KDC101Simulator._on_set_block for b in sm.BLOCKS},
    **{b.req_id: KDC101Simulator._on_req_block for b in sm.BLOCKS},
}

#: The shapes of the messages outside the driver's table (which the framer checks):
#: () header only, else the payload lengths accepted.
_SIM_SHAPES: dict[int, tuple[int, ...]] = {
    sm.SimMsgId.HW_DISCONNECT: (),
    sm.SimMsgId.HUB_REQ_BAYUSED: (),
    sm.SimMsgId.MOT_SET_ENCCOUNTER: (sm.CHAN_LONG.size,),
    sm.SimMsgId.MOT_REQ_ENCCOUNTER: (),
    sm.SimMsgId.MOT_MOVE_JOG: (),
    **{b.set_id: b.lengths() for b in sm.BLOCKS},
    **{b.req_id: () for b in sm.BLOCKS},
}


def _shape_error(msg: Message) -> str:
    """Why ``msg`` does not have its message's shape ('' when it does)."""
    lengths = _SIM_SHAPES.get(msg.msg_id)
    if lengths is None:  # the driver's table: the framer checked it
        return ""
    name = sm.SimMsgId(msg.msg_id).name
    got = "a header only" if msg.data is None else f"{len(msg.data)} data bytes"
    if not lengths:
        return "" if msg.data is None else f"{name}: {got}, expected a header only"
    if msg.data is None or len(msg.data) not in lengths:
        return f"{name}: {got}, expected {' or '.join(map(str, lengths))} data bytes"
    return ""


# Payloads (outside the driver's table) whose first word is the channel.
_DATA_WITH_CHANNEL = {sm.SimMsgId.MOT_SET_ENCCOUNTER, *(b.set_id for b in sm.BLOCKS)}

# Header-only requests whose param1 is the channel.
_CHANNEL_IN_PARAM1 = {
    MsgId.MOD_SET_CHANENABLESTATE, MsgId.MOD_REQ_CHANENABLESTATE, MsgId.MOT_REQ_POSCOUNTER,
    MsgId.MOT_REQ_VELPARAMS, MsgId.MOT_REQ_HOMEPARAMS, MsgId.MOT_REQ_LIMSWITCHPARAMS,
    MsgId.MOT_REQ_STATUSBITS, MsgId.MOT_REQ_DCSTATUSUPDATE, MsgId.MOT_MOVE_HOME,
    MsgId.MOT_MOVE_VELOCITY, MsgId.MOT_MOVE_STOP, MsgId.MOT_MOVE_RELATIVE,
    MsgId.MOT_MOVE_ABSOLUTE, sm.SimMsgId.MOT_REQ_ENCCOUNTER, sm.SimMsgId.MOT_MOVE_JOG,
    *(b.req_id for b in sm.BLOCKS),
}
