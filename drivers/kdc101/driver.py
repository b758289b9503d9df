"""The KDC101 + Z825B stage over APT: a ``Stage`` on any pyserial port or URL.

``KDC101("COM3").open()``, ``KDC101("/dev/ttyUSB0")``, ``KDC101("socket://host:port")`` or
``KDC101("kdc101sim://name", clock=clock)`` all run the same code; the constructor does no
I/O, ``open()`` (or ``with``) connects (ADR 0050). Every wait goes through the injected clock;
bad bytes are skipped (the framer resynchronises) and a lost reply is asked for once more,
within the same reply deadline (``StageConfig.reply_timeout_s``, ADR 0060); timeouts, device
error replies and a vanished port raise typed errors, and any fault while the stage may be
moving (Ctrl-C included) first commands MOT_MOVE_STOP. A move that would last longer than
``StageConfig.motion_bound_s`` goes out as bounded segments renewed by every later request
(ADR 0201), so the stage stops by itself within that bound if gelrig dies.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress

import serial
from serial.serialutil import SerialBase, SerialException

from gelrig.drivers.kdc101 import payloads as pl
from gelrig.drivers.kdc101.apt import (
    CHANNEL,
    AptFramer,
    AptFramingError,
    Message,
    MsgId,
    command,
    data_message,
    encode,
    message_name,
)
from gelrig.drivers.kdc101.segments import BoundedMove, SegmentPlan
from gelrig.instrument.contracts.stage import StageConfig, StageStatus
from gelrig.instrument.contracts.stop_first import stop_on_fault
from gelrig.instrument.core import wire
from gelrig.instrument.core.clock import Clock, RealClock
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    FramingError,
    GelrigError,
    InstrumentError,
    InstrumentTimeout,
    NotSent,
)
from gelrig.instrument.core.identity import Identity
from gelrig.instrument.core.stage_path import StagePath
from gelrig.instrument.core.timebase import PeriodicArrivals

BAUD = 115200
COMPLETIONS = {MsgId.MOT_MOVE_COMPLETED, MsgId.MOT_MOVE_STOPPED, MsgId.MOT_MOVE_HOMED}
KEEPALIVE_PERIOD_S = 0.5  # the controller wants an ack at least once a second
SOFT_LIMIT_STOP_PROFILED = 3  # LIMSWITCHPARAMS software-limit mode
#: Messages that end (or replace) any motion: a segmented move is not renewed after them.
_ENDS_SEGMENT = frozenset({MsgId.MOT_MOVE_STOP, MsgId.MOT_MOVE_HOME,
                           MsgId.MOD_SET_CHANENABLESTATE})
ARRIVAL_TOLERANCE_COUNTS = 2
#: A position report disagreeing with the commanded path by more than this is flagged.
PATH_TOLERANCE_COUNTS = 6
#: A status update whose window (narrowed by the stream's period, PeriodicArrivals) is wider
#: than this (s) is not taken as a report: it says little of when the stage was there.
UPDATE_WINDOW_MAX_S = 0.05
#: The status updates' period (APT document: "every 100 msec") and its relative
#: uncertainty (UNVERIFIED: the controller's crystal and firmware loop).
UPDATE_PERIOD_S = 0.1
UPDATE_PERIOD_TOLERANCE = 1e-3
#: Longest wait (s) for the stage to read back stopped after a stop sent while a request is
#: unanswered (a silent controller): the stop goes out at once, and a silent controller must
#: not add a whole reply timeout to the way out (ADR 0060).
SILENT_STOP_WAIT_S = 0.5
#: Requests (with their reply) that the driver may send to resynchronise after a request went
#: unanswered: harmless reads, each with a reply id of its own. APT replies carry no request
#: id, so a late reply is told from a fresh one by its place before the probe's reply.
SYNC_PROBES: tuple[tuple[int, int, int], ...] = (
    (MsgId.MOD_REQ_CHANENABLESTATE, CHANNEL, MsgId.MOD_GET_CHANENABLESTATE),
    (MsgId.HW_REQ_INFO, 0, MsgId.HW_GET_INFO),
    (MsgId.MOT_REQ_VELPARAMS, CHANNEL, MsgId.MOT_GET_VELPARAMS),
    (MsgId.MOT_REQ_HOMEPARAMS, CHANNEL, MsgId.MOT_GET_HOMEPARAMS),
    (MsgId.MOT_REQ_LIMSWITCHPARAMS, CHANNEL, MsgId.MOT_GET_LIMSWITCHPARAMS),
    (MsgId.MOT_REQ_POSCOUNTER, CHANNEL, MsgId.MOT_GET_POSCOUNTER),
    (MsgId.MOT_REQ_STATUSBITS, CHANNEL, MsgId.MOT_GET_STATUSBITS),
)


class KDC101:
    """Thorlabs KDC101 K-Cube DC servo controller with a Z825B actuator (implements Stage).

    Constructing does no I/O; :meth:`open` connects, identifies, enables and configures.

    Args:
        port: a port name or pyserial URL, or a pyserial port (opened by ``open()`` if it
            is not open yet, e.g. made with ``do_not_open=True``).
        config: calibration, software limits and timing (``StageConfig``).
        clock: what every wait goes through (the simulator's clock in virtual time).
        status_updates: ask for status messages every 100 ms (and keep them alive), each
            a position report to :attr:`path` within its arrival window; default the
            configuration's ``status_updates``.
    """

    def __init__(
        self,
        port: str | SerialBase,
        config: StageConfig | None = None,
        clock: Clock | None = None,
        *,
        status_updates: bool | None = None,
    ):
        self.config = config or StageConfig()
        self.clock: Clock = clock or RealClock()
        self._framer = AptFramer()
        self.framing_errors = 0
        self.ignored_messages = 0
        #: Replies to requests that went unanswered (timeout, garbage, Ctrl-C): they may still
        #: come (a frozen controller that resumes), so the next request resynchronises first.
        self._unanswered: set[int] = set()
        self.stale_replies = 0  # late replies dropped by a resynchronisation
        self.rts_supported = True
        self._maybe_moving = False
        #: The segmented move in progress (ADR 0201), renewed by the next request when due.
        self._segment: BoundedMove | None = None
        self._renewing = False
        self.renewals = 0  # segments renewed (diagnostics)
        self._status_updates = (self.config.status_updates if status_updates is None
                                else status_updates)
        #: When the input was last found empty (no byte waiting, no partial frame), and the
        #: window [opened, read] in which the bytes of the latest chunk read arrived.
        self._empty_at = -float("inf")
        self._drained_at: float | None = None
        self._arrival = (-float("inf"), -float("inf"))
        self.status_reports = 0  # status updates taken as position reports
        self.update_times = PeriodicArrivals(UPDATE_PERIOD_S, UPDATE_PERIOD_TOLERANCE)
        self._errors_seen = 0
        self._last_ack = -1e300
        self._last_update = -1e300
        self.last_status_update: pl.DcStatus | None = None
        self._port_timeout: float | None = None
        self._reply_cap = float("inf")  # a shorter reply deadline in force (s), see stop()
        self.reopens = 0  # new links opened after a lost one (reopen())
        self._given: str | SerialBase = port
        self._link: SerialBase | None = None
        self.address = port if isinstance(port, str) else str(port.port)
        self.identity: Identity | None = None
        #: The stage's path on the clock: every move and stop commanded, every position read
        #: (with the window it was taken in), for positions between reports (issue 24).
        self.path = StagePath(tolerance=PATH_TOLERANCE_COUNTS / (self.config.counts_per_mm * 1e3))
        self.max_velocity_m_s = self.config.max_velocity_m_s
        self.acceleration_m_s2 = self.config.acceleration_m_s2

    # ---- lifecycle --------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self._link is not None

    def open(self) -> KDC101:
        """Open the port, identify, enable the channel and configure it; returns self.

        A no-op if already open. On failure the port is closed again and the error raised.
        """
        if self._link is not None:
            return self
        self._new_link()
        try:
            self._open_sequence()
            self.identity = self.identify()
            self.enable()
            self._configure()
        except BaseException:
            self._close_port()
            raise
        return self

    def _new_link(self) -> None:
        """Connect to the address with nothing of an earlier link left over (framer,
        unanswered requests, the port's timeout)."""
        self._link = self._connect()
        self._framer.clear()
        self._unanswered.clear()
        self._port_timeout = None
        self._empty_at = self.clock.now()
        self.update_times.restart()

    def reopen(self) -> KDC101:
        """Close the link (lost or not) and open a new one to the same address: the open
        sequence and identification, not the configuration (the controller keeps its
        settings). For the safe stop after a lost link; InstrumentError if another
        controller answers there."""
        before = self.identity
        self._close_port()
        self._new_link()
        try:
            self._open_sequence()
            identity = self.identify()
        except BaseException:
            self._close_port()
            raise
        if before is not None and identity.serial != before.serial:
            self._close_port()
            raise InstrumentError(f"KDC101 at {self.address}: a new link reached serial "
                                  f"{identity.serial}, not {before.serial}")
        self.identity = identity
        self.reopens += 1
        return self

    def _connect(self) -> SerialBase:
        port = self._given

        def connect() -> SerialBase:
            if isinstance(port, str):
                return serial.serial_for_url(port, baudrate=BAUD, bytesize=8, parity="N",
                                             stopbits=1, rtscts=False, timeout=0)
            if not port.is_open:
                port.open()
            return port

        try:
            # recorded or replayed while a wire log is active (issue 30)
            return wire.serial_port("kdc101", self.clock, connect)
        except (SerialException, OSError, ValueError) as exc:
            raise Disconnected(f"KDC101: cannot open {self.address!r}: {exc}") from exc

    @property
    def _port(self) -> SerialBase:
        """The open port; Disconnected before ``open()`` or after ``close()``."""
        if self._link is None:
            raise Disconnected(f"KDC101 at {self.address}: not open (call open())")
        return self._link

    # ---- the open sequence ------------------------------------------------------------
    def _open_sequence(self) -> None:
        """Baud set; 50 ms; purge; 50 ms; RTS/CTS on; RTS set (a pty can't: tolerated)."""
        self.clock.sleep(0.05)
        try:
            self._port.reset_input_buffer()
            self._port.reset_output_buffer()
        except (SerialException, OSError) as exc:
            raise Disconnected(f"KDC101 at {self.address}: purge failed: {exc}") from exc
        self.clock.sleep(0.05)
        try:
            self._port.rtscts = True
            self._port.rts = True
        except (SerialException, OSError, ValueError):
            self.rts_supported = False  # e.g. a Linux pty: errno 25, no modem lines
        self._send(command(MsgId.HW_NO_FLASH_PROGRAMMING))
        self._send(command(MsgId.HW_START_UPDATEMSGS if self._status_updates
                           else MsgId.HW_STOP_UPDATEMSGS))
        if self._status_updates:
            self._last_update = self._last_ack = self.clock.now()

    def _configure(self) -> None:
        """Velocity, homing velocity and controller soft limits from the configuration."""
        c = self.config
        self.set_velocity(c.max_velocity_m_s, c.acceleration_m_s2)
        home = self.home_params()
        self._send(data_message(MsgId.MOT_SET_HOMEPARAMS, pl.HomeParams(
            home.direction, home.limit_switch, c.apt_velocity(c.home_velocity_m_s),
            home.offset).pack()))
        lim = self.limit_switch_params()
        self._send(data_message(MsgId.MOT_SET_LIMSWITCHPARAMS, pl.LimSwitchParams(
            lim.cw_hard, lim.ccw_hard, c.counts_from_m(c.max_position_m),
            c.counts_from_m(c.min_position_m), SOFT_LIMIT_STOP_PROFILED).pack()))
        if self.home_params().velocity != c.apt_velocity(c.home_velocity_m_s):
            raise InstrumentError(f"KDC101 at {self.address}: home velocity not accepted")

    # ---- bytes ------------------------------------------------------------------------
    def _send(self, msg: Message) -> None:
        if msg.msg_id in _ENDS_SEGMENT:
            self._segment = None  # a stop, homing or disable ends any segmented move first
        try:
            self._port.write(encode(msg))
        except (SerialException, OSError, ValueError) as exc:
            raise NotSent(f"KDC101 at {self.address}: write failed: {exc}") from exc

    def _read_chunk(self, deadline: float) -> None:
        remaining = deadline - self.clock.now()
        if remaining <= 0:
            return
        if self._port_timeout != remaining:
            self._port.timeout = remaining
            self._port_timeout = remaining
        opened = self._empty_at
        try:
            size = max(1, self._port.in_waiting)
            chunk = self._port.read(size)
            now = self.clock.now()
            if chunk:
                self._framer.feed(chunk)
                self._arrival = (opened, now)
                # drained if nothing more waits: confirmed in _await once the framer holds no
                # partial frame
                self._drained_at = now if not self._port.in_waiting else None
        except (SerialException, OSError, ValueError) as exc:
            raise Disconnected(f"KDC101 at {self.address}: read failed: {exc}") from exc
        if not chunk:
            self.clock.sleep_until(deadline)  # the port waited; keep the clock in step
            if not self._framer.pending:
                self._empty_at = self.clock.now()

    def _await(self, wanted: Callable[[Message], bool], deadline: float) -> Message | None:
        """The next wanted message before ``deadline`` (clock time), or None.

        Error replies raise DeviceErrorReply; status updates are kept and acknowledged;
        anything else unsolicited is ignored.
        """
        while True:
            self._keepalive()
            try:
                msg = self._framer.next_message()
            except AptFramingError:
                self.framing_errors += 1
                continue
            if msg is None:
                if self._drained_at is not None and not self._framer.pending:
                    self._empty_at, self._drained_at = self._drained_at, None
                if self.clock.now() >= deadline:
                    return None
                self._read_chunk(deadline)
                continue
            if msg.msg_id == MsgId.HW_RICHRESPONSE and msg.data is not None:
                rich = pl.RichResponse.unpack(msg.data)
                raise DeviceErrorReply(
                    f"KDC101 at {self.address} refused {message_name(rich.msg_id)}: "
                    f"{rich.text} (code {rich.code})", rich.code)
            if msg.msg_id == MsgId.HW_RESPONSE:
                raise DeviceErrorReply(f"KDC101 at {self.address} reported an error "
                                       f"(HW_RESPONSE, param {msg.param1})", msg.param1)
            if msg.msg_id == MsgId.MOT_GET_DCSTATUSUPDATE and msg.data is not None:
                self.last_status_update = pl.DcStatus.unpack(msg.data)
                self._last_update = self.clock.now()
                self._status_report(self.last_status_update)
            if wanted(msg):
                return msg
            if msg.msg_id not in COMPLETIONS and msg.msg_id != MsgId.MOT_GET_DCSTATUSUPDATE:
                self.ignored_messages += 1

    def _status_report(self, status: pl.DcStatus) -> None:
        """A status update as a position report: the controller sent it after the input was
        last found empty (less the link's latency, ``StageConfig.link_latency_s``) and before
        the read that brought it, narrowed by the stream's period (:attr:`update_times`).
        None while homing (the counter's origin moves at its end)."""
        if not self._status_updates:
            return
        if self.framing_errors != self._errors_seen:  # bytes lost: an update may be missing
            self._errors_seen = self.framing_errors
            self.update_times.restart()
        lo, hi = self._arrival
        if not hi > lo:
            self.update_times.skip()  # counted: the next ones keep their place in the stream
            return
        lo, hi = self.update_times.add(lo - self.config.link_latency_s, hi)
        if status.bits & pl.HOMING or not hi - lo <= UPDATE_WINDOW_MAX_S:
            return  # homing moves the counter's origin; a wide window says little
        self.path.reported(lo, hi, self.config.m_from_counts(status.position), source="update")
        self.status_reports += 1

    def _keepalive(self) -> None:
        if not self._status_updates:
            return
        now = self.clock.now()
        if now - self._last_update > 1.0:
            # The stream stopped (about 50 unacknowledged messages): ask for it again.
            self._send(command(MsgId.HW_START_UPDATEMSGS))
            self.update_times.restart()
            self._last_update = self._last_ack = now
        elif now - self._last_ack >= KEEPALIVE_PERIOD_S:
            self._send(command(MsgId.MOT_ACK_DCSTATUSUPDATE))
            self._last_ack = now

    def _query(self, request: Message, reply_id: int, timeout: float | None = None) -> Message:
        """Send ``request`` and return its reply within ``timeout`` (reply_timeout_s) in all.

        If only invalid bytes came in the first half of the deadline (garbage ate the reply),
        the request is sent once more and the second half waits for that answer: a retry
        never extends the deadline (ADR 0060). After a request went unanswered, the first
        query resynchronises within the same deadline (:meth:`_resync`).
        """
        if self._segment is not None and not self._renewing:
            self._renew_segment()
        timeout = self.config.reply_timeout_s if timeout is None else timeout
        end = self.clock.now() + min(timeout, self._reply_cap)
        try:
            if self._unanswered:
                self._resync(end, request.name)
            reply = self._exchange(request, reply_id, end)
        except BaseException:
            self._unanswered.add(reply_id)  # it may still come, late
            raise
        return reply

    def _exchange(self, request: Message, reply_id: int, end: float) -> Message:
        """Send ``request``; its reply before ``end`` (one resend after garbage, see _query)."""
        errors_before = self.framing_errors
        start = self.clock.now()

        def wanted(m: Message) -> bool:
            return m.msg_id == reply_id

        self._send(request)
        reply = self._await(wanted, start + (end - start) / 2)
        if reply is None:
            self._drop_partial_frame()
            if self.framing_errors > errors_before:
                self._send(request)
            reply = self._await(wanted, end)
        if reply is not None:
            return reply
        self._drop_partial_frame()
        what = (f"no {message_name(reply_id)} within {end - start:.3g} s after "
                f"{request.name}")
        if self.framing_errors > errors_before:
            raise FramingError(f"KDC101 at {self.address}: {what} (only invalid bytes came: "
                               f"{self._framer.discarded} skipped so far)")
        raise InstrumentTimeout(f"KDC101 at {self.address}: {what}")

    def _resync(self, end: float, before: str) -> None:
        """Drop late replies to unanswered requests before a new request is sent.

        The input is discarded, then a harmless probe whose reply id no unanswered request
        shares is sent; the controller answers in order, so whatever comes before the probe's
        reply is late (dropped, error replies included). If the probe is not answered by
        ``end`` the instrument is still silent: InstrumentTimeout, and the next query tries
        again with another probe.
        """
        self._discard_input()
        probe = next((p for p in SYNC_PROBES if p[2] not in self._unanswered), None)
        if probe is None:  # every probe is pending too: the input discarded is all we can do
            return
        msg_id, param1, reply_id = probe
        self._unanswered.add(reply_id)
        self._send(command(msg_id, param1))
        while True:
            try:
                reply = self._await(lambda m: True, end)
            except DeviceErrorReply:
                self.stale_replies += 1  # an error reply to an old request
                continue
            if reply is None:
                self._drop_partial_frame()
                raise InstrumentTimeout(
                    f"KDC101 at {self.address}: still silent after an unanswered request: no "
                    f"{message_name(reply_id)} to a resynchronising {message_name(msg_id)} "
                    f"before {before}; {before} not sent")
            if reply.msg_id == reply_id:
                self._unanswered.clear()
                return
            if reply.msg_id != MsgId.MOT_GET_DCSTATUSUPDATE and reply.msg_id not in COMPLETIONS:
                self.stale_replies += 1

    def _drop_partial_frame(self) -> None:
        """A truncated frame stuck in the buffer counts as a framing error and is dropped."""
        if self._framer.pending:
            self.framing_errors += 1
            self._framer.clear()

    def _req(self, msg_id: int, reply_id: int) -> Message:
        return self._query(command(msg_id, CHANNEL), reply_id)

    @staticmethod
    def _data(msg: Message) -> bytes:
        return msg.data or b""

    # ---- safety -----------------------------------------------------------------------
    @contextmanager
    def _guard(self) -> Iterator[None]:
        """On any failure (Ctrl-C included) while the stage may be moving, stop, re-raise.

        An exchange cut short (Ctrl-C) may leave its reply unread, which the next request of
        the same kind would take for its own: the input is dropped first.
        """
        with stop_on_fault(self._emergency_stop, needed=lambda: self._maybe_moving,
                           what=f"KDC101 at {self.address}"):
            try:
                yield
            except GelrigError:
                raise
            except BaseException:
                self._discard_input()
                raise

    def _discard_input(self) -> None:
        self._framer.clear()
        self.update_times.restart()
        with suppress(InstrumentError, SerialException, OSError, ValueError):
            self._port.reset_input_buffer()

    def _emergency_stop(self) -> None:
        self._send(command(MsgId.MOT_MOVE_STOP, CHANNEL, pl.STOP_IMMEDIATE))

    # ---- Stage: identity and set-up ---------------------------------------------------
    def identify(self) -> Identity:
        """Ask the controller (HW_REQ_INFO); InstrumentError if it is not a KDC101."""
        info = pl.HwInfo.unpack(self._data(self._query(command(MsgId.HW_REQ_INFO),
                                                       MsgId.HW_GET_INFO)))
        if not info.model.startswith("KDC101"):
            raise InstrumentError(f"{self.address}: expected a KDC101, found {info.model!r} "
                                  f"(serial {info.serial_number})")
        self.hw_info = info
        return stage_identity(info.model, info.serial_number,
                              ".".join(str(n) for n in info.firmware), info.hw_version,
                              info.n_channels)

    def enable(self) -> None:
        with self._guard():
            self._send(command(MsgId.MOD_SET_CHANENABLESTATE, CHANNEL, pl.CHAN_ENABLED))
            state = self._req(MsgId.MOD_REQ_CHANENABLESTATE, MsgId.MOD_GET_CHANENABLESTATE)
            if state.param2 != pl.CHAN_ENABLED:
                raise InstrumentError(f"KDC101 at {self.address}: channel did not enable")

    def disable(self) -> None:
        """De-energise the motor (stops any motion)."""
        self.path.lost(self.clock.now())
        self._send(command(MsgId.MOD_SET_CHANENABLESTATE, CHANNEL, pl.CHAN_DISABLED))

    def velocity_params(self) -> pl.VelParams:
        return pl.VelParams.unpack(self._data(self._req(MsgId.MOT_REQ_VELPARAMS,
                                                        MsgId.MOT_GET_VELPARAMS)))

    def home_params(self) -> pl.HomeParams:
        return pl.HomeParams.unpack(self._data(self._req(MsgId.MOT_REQ_HOMEPARAMS,
                                                         MsgId.MOT_GET_HOMEPARAMS)))

    def limit_switch_params(self) -> pl.LimSwitchParams:
        return pl.LimSwitchParams.unpack(self._data(self._req(MsgId.MOT_REQ_LIMSWITCHPARAMS,
                                                              MsgId.MOT_GET_LIMSWITCHPARAMS)))

    def set_velocity(self, max_m_s: float, accel_m_s2: float) -> None:
        self.config.check_velocity(max_m_s, accel_m_s2)
        c = self.config
        wanted = pl.VelParams(0, c.apt_acceleration(accel_m_s2), c.apt_velocity(max_m_s))
        with self._guard():
            self._send(data_message(MsgId.MOT_SET_VELPARAMS, wanted.pack()))
            got = self.velocity_params()
            if got != wanted:
                raise InstrumentError(f"KDC101 at {self.address}: velocity parameters not "
                                      f"accepted (sent {wanted}, read back {got})")
        self.max_velocity_m_s, self.acceleration_m_s2 = max_m_s, accel_m_s2

    # ---- Stage: motion ----------------------------------------------------------------
    def home(self, wait: bool = True, timeout: float | None = None) -> None:
        with self._guard():
            self._maybe_moving = True
            self.path.lost(self.clock.now())
            self._send(command(MsgId.MOT_MOVE_HOME, CHANNEL))
            self.status()  # surfaces an error reply to the command now
            if wait:
                self.wait_until_stopped(timeout)
                if not self.status().homed:
                    raise InstrumentError(f"KDC101 at {self.address}: homing did not complete")
                self._position_counts()  # where the path starts again, in the homed frame

    def move_to(self, position_m: float, wait: bool = True, timeout: float | None = None) -> None:
        self.config.check_position(position_m)  # LimitError: nothing sent, nothing moved
        target = self.config.counts_from_m(position_m)
        with self._guard():
            self._maybe_moving = True  # an error reply from here on may concern a move
            start = self._position_counts()
            self._start_move(start, target)
            self.status()
            if wait:
                self.wait_until_stopped(timeout)
                self._check_arrival(target)

    def move_by(self, distance_m: float, wait: bool = True, timeout: float | None = None) -> None:
        with self._guard():
            start = self._position_counts()
            self.config.check_position(self.config.m_from_counts(start) + distance_m)
            steps = self.config.counts_from_m(distance_m)
            self._maybe_moving = True
            if self._plan().fits(distance_m):  # ends within the bound: one command
                self._segment = None
                lo = self.clock.now()
                self._send(data_message(MsgId.MOT_MOVE_RELATIVE, pl.pack_position(steps)))
                self._commanded(lo, start + steps)
            else:
                self._start_move(start, start + steps)
            self.status()
            if wait:
                self.wait_until_stopped(timeout)
                self._check_arrival(start + steps)

    def move_velocity(self, direction: int) -> None:
        """Run at the set velocity until ``stop``, at most to the software travel limit.

        Sent as bounded segments towards that limit, never as MOT_MOVE_VELOCITY (ADR 0201):
        the speed is the same while gelrig renews them, and the stage stops within
        ``motion_bound_s`` when it does not.
        """
        if direction not in (1, -1):
            raise ValueError(f"direction must be +1 or -1, got {direction}")
        c = self.config
        end = c.counts_from_m(c.max_position_m if direction > 0 else c.min_position_m)
        with self._guard():
            self._maybe_moving = True
            start = self._position_counts()
            if (end - start) * direction <= 0:
                return  # at the limit already: nothing to move
            self._start_move(start, end)
            self.status()

    def keep_alive(self) -> None:
        """Renew the segmented move in progress if it is due (ADR 0201); else nothing."""
        if self._segment is None:
            return
        with self._guard():
            self._renew_segment()

    # ---- bounded segments (ADR 0201) --------------------------------------------------
    def _plan(self) -> SegmentPlan:
        return SegmentPlan.of(self.max_velocity_m_s, self.acceleration_m_s2,
                              self.config.motion_bound_s)

    def _start_move(self, start: int, final: int) -> None:
        """Move from ``start`` to ``final`` (counts): one MOT_MOVE_ABSOLUTE if the move ends
        within the bound, else its first segment."""
        plan = self._plan()
        cpm = self.config.counts_per_mm * 1e3
        lo = self.clock.now()
        if plan.fits((final - start) / cpm):
            self._segment = None
            self._send(data_message(MsgId.MOT_MOVE_ABSOLUTE, pl.pack_position(final)))
        else:
            move = BoundedMove(final, 1 if final > start else -1, plan.lookahead * cpm, plan,
                               final, lo)
            self._send_segment(move, move.next_target(start))
        # renewed in time, the segments follow the profile of one move to ``final`` (ADR 0201)
        self._commanded(lo, final)

    def _commanded(self, lo: float, target_counts: int) -> None:
        """Tell the path of a move to ``target_counts`` whose command went out from ``lo`` to
        now, at the speed and acceleration the controller holds (its APT units)."""
        c = self.config
        speed = c.velocity_from_apt(c.apt_velocity(self.max_velocity_m_s))
        accel = c.accel_from_apt(c.apt_acceleration(self.acceleration_m_s2))
        self.path.commanded(lo, self.clock.now(), c.m_from_counts(target_counts), speed, accel)

    def _send_segment(self, move: BoundedMove, target: float) -> None:
        counts = int(target) if target == move.final else round(target)
        self._send(data_message(MsgId.MOT_MOVE_ABSOLUTE, pl.pack_position(counts)))
        if counts == move.final:
            self._segment = None  # the last segment: the move now ends by itself
        else:
            move.target, move.renewed_at = counts, self.clock.now()
            self._segment = move

    def _renew_segment(self) -> None:
        """Send the next segment if it is due: a target ``lookahead`` ahead of the stage.

        A renewal later than the plan's ``late_after`` raises InstrumentError (the guard then
        stops the stage): the stage may already have slowed down or stopped short, so the
        move is no longer the one commanded.
        """
        move = self._segment
        now = self.clock.now()
        if move is None or not move.due(now):
            return
        if move.late(now):
            self._segment = None
            cpm = self.config.counts_per_mm * 1e3
            raise InstrumentError(
                f"KDC101 at {self.address}: a move segment was renewed "
                f"{now - move.renewed_at:.2f} s after the last (at most "
                f"{move.plan.late_after:.2f} s keeps the speed profile): gelrig stalled, so "
                f"the stage may have stopped short of {move.final / cpm * 1e3:.4f} mm; the "
                "move is abandoned (ADR 0201)")
        self._renewing = True
        try:
            position = self._position_counts()
        finally:
            self._renewing = False
        if self._segment is not move:
            return  # a stop (or another move) came in the meantime: nothing to renew
        self.renewals += 1
        self._send_segment(move, move.next_target(position))

    def stop(self, immediate: bool = True) -> None:
        """Send MOT_MOVE_STOP; an immediate stop waits until the stage reads back stopped
        (at most ``reply_timeout``, or :data:`SILENT_STOP_WAIT_S` per reply while a request
        is unanswered: a silent controller is not waited for twice)."""
        mode = pl.STOP_IMMEDIATE if immediate else pl.STOP_PROFILED
        silent = bool(self._unanswered)
        with self._guard():
            lo = self.clock.now()
            self._send(command(MsgId.MOT_MOVE_STOP, CHANNEL, mode))
            c = self.config
            self.path.stopped(lo, self.clock.now(), immediate,
                              c.accel_from_apt(c.apt_acceleration(self.acceleration_m_s2)))
            if immediate:
                self._reply_cap = SILENT_STOP_WAIT_S if silent else float("inf")
                try:
                    self.wait_until_stopped(self.config.reply_timeout_s)
                finally:
                    self._reply_cap = float("inf")

    def _check_arrival(self, target: int) -> None:
        counts = self._position_counts()
        if abs(counts - target) > ARRIVAL_TOLERANCE_COUNTS:
            st = self.status()
            where = "a limit switch" if st.at_lower_limit or st.at_upper_limit else "a stop"
            raise InstrumentError(
                f"KDC101 at {self.address}: stopped at {counts} counts by {where}, "
                f"target was {target} counts")

    def wait_until_stopped(self, timeout: float | None = None) -> None:
        limit = self.config.move_timeout_s if timeout is None else timeout
        deadline = self.clock.now() + limit
        with self._guard():
            while True:
                if not self.status().busy:
                    self._maybe_moving = False
                    return
                if self.clock.now() >= deadline:
                    raise InstrumentTimeout(f"KDC101 at {self.address}: still moving after "
                                            f"{limit} s")
                slice_end = min(self.clock.now() + self.config.poll_interval_s, deadline)
                self._await(lambda m: m.msg_id in COMPLETIONS, slice_end)

    # ---- Stage: readings --------------------------------------------------------------
    def _position_counts(self) -> int:
        lo = self.clock.now()
        _, counts = pl.unpack_position(self._data(self._req(MsgId.MOT_REQ_POSCOUNTER,
                                                            MsgId.MOT_GET_POSCOUNTER)))
        self.path.reported(lo, self.clock.now(), self.config.m_from_counts(counts))
        return counts

    def position_counts(self) -> int:
        """The encoder counter (device units), for calibration checks."""
        with self._guard():
            return self._position_counts()

    def position(self) -> float:
        return self.config.m_from_counts(self.position_counts())

    def status(self) -> StageStatus:
        with self._guard():
            _, bits = pl.unpack_statusbits(self._data(self._req(MsgId.MOT_REQ_STATUSBITS,
                                                                MsgId.MOT_GET_STATUSBITS)))
            return pl.decode_status(bits, self.config.direction)

    def is_moving(self) -> bool:
        return self.status().busy

    def close(self) -> None:
        """Stop the status stream and release the port (does not move the stage); idempotent."""
        if self._link is None:
            return
        try:
            if self._status_updates:
                self._send(command(MsgId.HW_STOP_UPDATEMSGS))
        except InstrumentError:
            pass
        finally:
            self._close_port()

    def _close_port(self) -> None:
        # pyserial's socket:// close skips socket.close() when shutdown() fails on a peer
        # that already hung up; close it ourselves so the descriptor is not leaked.
        port, self._link = self._link, None
        if port is None:
            return
        sock = getattr(port, "_socket", None)
        port.close()
        if sock is not None:
            sock.close()

    def __enter__(self) -> KDC101:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()


def stage_identity(model: str, serial_number: int, firmware: str, hardware_version: int,
                   channels: int) -> Identity:
    """The Identity of a KDC101 from its HW_GET_INFO fields (shared by both backends).

    ``extra`` keeps run.json's former stage keys: serial_number, hardware_version, channels.
    """
    return Identity("Thorlabs", model, str(serial_number), firmware, str(hardware_version),
                    extra={"serial_number": str(serial_number),
                           "hardware_version": str(hardware_version),
                           "channels": str(channels)})
