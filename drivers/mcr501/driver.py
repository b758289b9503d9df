"""The MCR 501 driver: the :class:`gelrig.instrument.contracts.rheometer.Rheometer` contract over
pyvisa.

Every request goes through the command table (drivers/mcr501/commands.py, UNCONFIRMED on
hardware). SI units at the interface; wire units (mm, deg, rpm, mN m) inside. Waits run on the
injected clock, so in virtual time a gap move or a pass costs no wall time. The constructor
does no I/O; ``open()`` (or ``with``) connects and identifies (ADR 0050). Safe by default: any
failure of a method while the arm may be turning, Ctrl-C included, sends stop before the error
propagates (gelrig.instrument.contracts.stop_first). The arm turns only in time-limited
segments (``:ROT[dir;rpm;duration]``) that every later request renews while gelrig runs, so the
instrument ends a rotation by itself within ``RheometerConfig.motion_bound`` if gelrig dies
(docs/decisions/0201).
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from gelrig.drivers.mcr501.codec import (
    RECORD_FIELDS,
    RECORD_MIN_LENGTH,
    Values,
    decode_record_rows,
    decode_reply,
    decode_stream_header,
    record_rest,
)
from gelrig.drivers.mcr501.commands import BAUD_RATE, COMMANDS, STATUS_FLAGS, split_key
from gelrig.drivers.mcr501.transport import LineTransport, VisaTransport
from gelrig.instrument.contracts.rheometer import RheometerConfig, RheometerStatus, StreamBlock
from gelrig.instrument.contracts.stop_first import guarded, stop_on_fault
from gelrig.instrument.core import wire
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import (
    Disconnected,
    FramingError,
    GelrigError,
    InstrumentError,
    InstrumentTimeout,
    LimitError,
)
from gelrig.instrument.core.identity import Identity
from gelrig.instrument.physics.sliding import rpm_from_speed

log = logging.getLogger(__name__)

_MODES = {"IDLE": "idle", "ROT": "rotating", "HOLD": "holding"}
#: Shortest stream interval the driver asks for (s).
MIN_STREAM_INTERVAL = 1e-3
#: Longest wait (s) for the acknowledgement of a stop sent after a fault (ADR 0060): the stop
#: goes out at once; a silent instrument must not double the time to report the fault.
STOP_ACK_TIMEOUT_S = 0.5
_STREAM_REQUEST = COMMANDS["read_stream"].request.encode()
_MILLI = np.array(1e-3)
#: A record later than this many intervals after the one before it means points were lost.
GAP_TOLERANCE = 1.5
#: A rotation segment lasts this fraction of ``motion_bound`` on the instrument (the rest of
#: the bound is for its ramp to rest), and is renewed after ``RENEW_FRACTION`` of it
#: (docs/decisions/0201).
SEGMENT_FRACTION = 0.75
RENEW_FRACTION = 0.25
_RENEW_TOLERANCE_S = 1e-9


#: Commands after which no rotation is renewed (a time-limited one renews itself).
_ENDS_ROTATION = frozenset({"stop", "hold", "rotate"})


class StreamOverflow(InstrumentError):
    """The instrument's stream buffer overflowed: it dropped points before they were read."""


class MCR501:
    """Anton Paar MCR 501 with the rotating-arm shear tool, over any line transport.

    ``transport`` is a VISA resource string (a :class:`VisaTransport` is made by ``open()``,
    ASRL resources at 38400 baud 8N1 XON/XOFF by default, through ``backend`` or a shared
    ``resource_manager``) or a ready :class:`LineTransport` (the simulator's DirectLink).
    Constructing does no I/O.
    """

    def __init__(
        self,
        transport: LineTransport | str,
        clock: Clock,
        config: RheometerConfig | None = None,
        *,
        backend: str = "@py",
        resource_manager: Any = None,
        baud_rate: int = BAUD_RATE,
    ):
        self._given = transport
        self._link: LineTransport | None = None
        self._clock = clock
        self._config = config if config is not None else RheometerConfig()
        self._backend, self._resource_manager, self._baud_rate = (
            backend, resource_manager, baud_rate)
        self._maybe_rotating = False
        #: The rotation being renewed, (direction, rpm), and when it was last sent (ADR 0201).
        self._rotation: tuple[str, float] | None = None
        self._rotation_sent = 0.0
        self._renewing = False
        self.renewals = 0
        self._resync = False  # a reply may still be on its way after a fault: drain first
        self._stream_t0: float | None = None
        #: half the window (s) in which the stream started: its times' uncertainty on the clock
        self.stream_start_uncertainty = math.nan
        self._stream_interval = 0.0
        self._stream_last = 0.0  # instrument time (s since :RUN) of the last record read
        self._loss_reported = False  # StreamOverflow raised for this stream already
        self.touch_gap: float | None = self._config.touch_gap
        self.identity: Identity | None = None

    # -- lifecycle -------------------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        return self._link is not None

    def open(self) -> MCR501:
        """Connect (a VISA resource) and identify; returns self. A no-op if already open."""
        if self._link is not None:
            return self
        given = self._given
        # recorded or replayed while a wire log is active (issue 30)
        if isinstance(given, str):
            self._link = wire.line_transport("mcr501", self._clock, lambda: VisaTransport(
                given, timeout=self._config.timeout, backend=self._backend,
                resource_manager=self._resource_manager, baud_rate=self._baud_rate))
        else:
            self._link = wire.line_transport("mcr501", self._clock, lambda: given)
        try:
            self.identity = self.identify()
        except BaseException:
            self._release()
            raise
        return self

    def __enter__(self) -> MCR501:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def reopen(self) -> MCR501:
        """Release the link (lost or not) and open a new one to the same VISA resource, then
        identify; for the safe stop after a lost link. Disconnected for a link given ready
        made (nothing to open again); InstrumentError if another instrument answers."""
        given = self._given
        if not isinstance(given, str):
            raise Disconnected("MCR 501: the link was given ready made; it cannot be reopened")
        before = self.identity
        self._release()
        self._resync = False
        self._link = wire.line_transport("mcr501", self._clock, lambda: VisaTransport(
            given, timeout=self._config.timeout, backend=self._backend,
            resource_manager=self._resource_manager, baud_rate=self._baud_rate))
        try:
            identity = self.identify()
        except BaseException:
            self._release()
            raise
        if before is not None and identity.serial != before.serial:
            self._release()
            raise InstrumentError(f"MCR 501 on {given}: a new link reached serial "
                                  f"{identity.serial}, not {before.serial}")
        self.identity = identity
        return self

    @property
    def _transport(self) -> LineTransport:
        """The open transport; Disconnected before ``open()`` or after ``close()``."""
        if self._link is None:
            raise Disconnected("MCR 501: not open (call open())")
        return self._link

    @property
    def config(self) -> RheometerConfig:
        return self._config

    @property
    def maybe_rotating(self) -> bool:
        """True from a rotate request until a stop or hold is acknowledged."""
        return self._maybe_rotating

    # -- wire ------------------------------------------------------------------------------

    def _transact(self, name: str, **values: object) -> Values:
        if name in _ENDS_ROTATION:
            self._rotation = None  # a stop or a new speed: nothing to renew any more
        elif self._rotation is not None and not self._renewing:
            self._renew_rotation()
        command = COMMANDS[name]
        self._send(command.request.encode(**values))
        return decode_reply(command, self._transport.read_line())

    def _send(self, line: str) -> None:
        """Write a request line, draining first if a late reply may be on its way."""
        if self._resync:
            self._resync = False
            self._drain()
        self._transport.write_line(line)

    @contextlib.contextmanager
    def _guard(self) -> Iterator[None]:
        """Any failure while the arm may turn sends stop first (contracts.stop_first).

        A timeout, a framing error or an interrupted exchange (Ctrl-C) may leave a reply
        unread: the input is drained so that the next reply lines up with its request.
        """
        with stop_on_fault(self._emergency_stop, needed=lambda: self._maybe_rotating,
                           what="MCR 501"):
            try:
                yield
            except BaseException as exc:
                if isinstance(exc, InstrumentTimeout | FramingError) or not isinstance(
                    exc, GelrigError
                ):
                    self._drain()
                    self._resync = True  # a late reply (a frozen instrument that resumes)
                raise

    def _drain(self) -> None:
        with contextlib.suppress(InstrumentError):
            self._transport.discard_input()

    def _emergency_stop(self) -> None:
        """Send stop, once more if its answer came garbled; raise the last failure.

        The acknowledgement is awaited at most STOP_ACK_TIMEOUT_S (never longer than the
        reply timeout), and an unanswered stop is not repeated (a silent instrument would
        not answer the second either), so a fault is reported within about timeout + 0.5 s.
        """
        for attempt in (1, 2):
            try:
                with self._transport.reply_timeout(STOP_ACK_TIMEOUT_S):
                    self._transact("stop")
            except InstrumentError as exc:
                self._drain()
                self._resync = True  # its answer may still come, late
                if attempt == 2 or isinstance(exc, InstrumentTimeout | Disconnected):
                    raise
                continue
            self._maybe_rotating = False
            return

    # -- identity and state ----------------------------------------------------------------

    @guarded
    def identify(self) -> Identity:
        """Ask the instrument; ``extra["identity"]`` keeps run.json's former one-line form."""
        v = self._transact("identify")
        model, serial, firmware = str(v["model"]), str(v["serial"]), str(v["firmware"])
        return Identity("Anton Paar", model, serial, firmware,
                        extra={"identity": f"{model} {serial} firmware {firmware}"})

    @guarded
    def status(self) -> RheometerStatus:
        return self._status()

    def _status(self) -> RheometerStatus:
        v = self._transact("status")
        flags = int(v["flags"])

        def bit(name: str) -> bool:
            return bool(flags & STATUS_FLAGS[name])

        return RheometerStatus(
            mode=_MODES[str(v["mode"])],
            gap_moving=bit("gap_moving"),
            gap_referenced=bit("gap_referenced"),
            streaming=bit("streaming"),
            accelerating=bit("accelerating"),
            fault=bit("fault"),
            overflow=bit("overflow"),
        )

    # -- gap -------------------------------------------------------------------------------

    @guarded
    def zero_gap(self) -> None:
        self._transact("zero_gap")
        self._wait_for_lift()

    @guarded
    def set_gap(self, gap: float, wait: bool = True) -> None:
        deepest = self._deepest_gap()
        if not (math.isfinite(gap) and deepest <= gap <= self._config.gap_max):
            why = (
                f" (overlap limit {self._config.overlap_limit * 1e3:g} mm below the touch gap "
                f"{self.touch_gap * 1e3:g} mm)"
                if self.touch_gap is not None
                else ""
            )
            raise LimitError(
                f"MCR 501: gap {gap * 1e3:g} mm outside the allowed "
                f"[{deepest * 1e3:g}, {self._config.gap_max * 1e3:g}] mm{why}; nothing moved"
            )
        self._transact("set_gap", gap_mm=gap * 1e3)
        if wait:
            self._wait_for_lift()

    def _deepest_gap(self) -> float:
        if self.touch_gap is None:
            return self._config.gap_min
        return max(self._config.gap_min, self.touch_gap - self._config.overlap_limit)

    def _wait_for_lift(self) -> None:
        deadline = self._clock.now() + self._config.gap_move_timeout
        while self._status().gap_moving:
            if self._clock.now() >= deadline:
                raise InstrumentTimeout(
                    f"MCR 501: the lift did not arrive within {self._config.gap_move_timeout:g} s"
                )
            self._clock.sleep(self._config.poll_interval)

    @guarded
    def gap(self) -> float:
        return float(self._transact("read_gap")["gap_mm"]) * 1e-3

    # -- rotation --------------------------------------------------------------------------

    @guarded
    def rotate(self, speed: float) -> None:
        """Turn at ``speed`` m/s at the arm; positive is clockwise (increasing angle)."""
        if not self._config.speed_allowed(speed):
            raise LimitError(
                f"MCR 501: speed {speed:g} m/s beyond max_speed {self._config.max_speed:g} m/s;"
                " not sent"
            )
        if speed == 0:
            self._stop()
            return
        rpm = rpm_from_speed(abs(speed), self._config.arm)
        self._maybe_rotating = True
        self._send_rotation(("CW" if speed > 0 else "CCW", rpm))

    @guarded
    def keep_alive(self) -> None:
        """Renew the rotation in progress if it is due (ADR 0201); else nothing."""
        if self._rotation is not None:
            self._renew_rotation()

    @property
    def segment_s(self) -> float:
        """How long one rotation segment lasts on the instrument (s)."""
        return SEGMENT_FRACTION * self._config.motion_bound

    def _send_rotation(self, rotation: tuple[str, float]) -> None:
        """A time-limited rotation: ``segment_s`` on the instrument, renewed by later calls."""
        sent = self._clock.now()
        self._renewing = True
        try:
            self._transact("rotate_for", direction=rotation[0], rpm=rotation[1],
                           duration_s=self.segment_s)
        finally:
            self._renewing = False
        self._rotation, self._rotation_sent = rotation, sent

    def _renew_rotation(self) -> None:
        """Send the rotation again if due. Later than its segment lasts, the instrument has
        begun to ramp to rest: InstrumentError (stop first), the rotation is abandoned."""
        rotation, now = self._rotation, self._clock.now()
        elapsed = now - self._rotation_sent
        if rotation is None or elapsed < RENEW_FRACTION * self._config.motion_bound \
                - _RENEW_TOLERANCE_S:
            return
        if elapsed > self.segment_s:
            self._rotation = None
            raise InstrumentError(
                f"MCR 501: the rotation was renewed {elapsed:.2f} s after it was last sent, "
                f"later than its {self.segment_s:g} s segment: gelrig stalled and the arm has "
                "begun to stop by itself; the rotation is abandoned (docs/decisions/0201)")
        self.renewals += 1
        self._send_rotation(rotation)

    def stop(self) -> None:
        """Stop the arm. After a reply went missing (a silent instrument) the stop's
        acknowledgement is awaited at most STOP_ACK_TIMEOUT_S, as after a fault."""
        if not self._resync:
            with self._guard():
                self._stop()
            return
        self._emergency_stop()

    def _stop(self) -> None:
        self._transact("stop")
        self._maybe_rotating = False

    @guarded
    def hold(self) -> None:
        self._transact("hold")
        self._maybe_rotating = False

    @guarded
    def exchange(self, line: str) -> list[str]:
        """Send ``line`` as written and return its reply lines, unchecked: the reply line,
        and after a ``#DATA[count;remaining]`` header its ``count`` record lines. What
        bring-up checks the command table with (issue 30); a ``:ROT`` line counts as a
        rotation until a stop or hold is answered, so a fault still stops the arm first."""
        if line.startswith(":ROT"):
            self._maybe_rotating = True
        self._send(line)
        reply = self._transport.read_line()
        out = [reply]
        head = split_key(reply)
        if head is not None and head[0] == "#DATA":
            count = head[1].split(";")[0]
            if count.isdigit() and int(count):
                out += self._transport.read_lines(int(count))
        if line.split("[")[0] in (":STOP", ":HOLD") and reply.endswith("[OK]"):
            self._maybe_rotating = False
        return out

    # -- readings --------------------------------------------------------------------------

    @guarded
    def angle(self) -> float:
        return math.radians(float(self._transact("read_angle")["angle_deg"]))

    def theta(self) -> float:
        return self.angle() * self._config.arm

    @guarded
    def torque(self) -> float:
        return float(self._transact("read_torque")["torque_mnm"]) * 1e-3

    @guarded
    def normal_force(self) -> float:
        return float(self._transact("read_normal_force")["force_n"])

    # -- measurement stream ----------------------------------------------------------------

    @guarded
    def start_stream(self, interval: float) -> None:
        if not (math.isfinite(interval) and interval >= MIN_STREAM_INTERVAL):
            raise LimitError(
                f"MCR 501: stream interval {interval!r} s; allowed >= {MIN_STREAM_INTERVAL:g} s"
            )
        lo = self._clock.now()
        self._transact("start_stream", interval_s=interval)
        hi = self._clock.now()
        # the stream's time 0 is when the instrument took the command: within [lo, hi]
        self._stream_t0 = 0.5 * (lo + hi)
        self.stream_start_uncertainty = 0.5 * (hi - lo)
        self._stream_interval, self._stream_last = interval, 0.0
        self._loss_reported = False

    @guarded
    def read_stream(self) -> StreamBlock:
        """Every point recorded since the last read, as columns; times on the caller's clock.

        Records come every stream interval; a record later than GAP_TOLERANCE intervals
        after the previous one means the instrument dropped points (its buffer overflowed):
        StreamOverflow, naming how many and when, instead of a silent hole in the data.
        """
        if self._rotation is not None:
            self._renew_rotation()
        t0 = 0.0 if self._stream_t0 is None else self._stream_t0
        values: list[float] = []
        transport = self._transport
        while True:
            self._send(_STREAM_REQUEST)
            count, remaining = decode_stream_header(transport.read_line())
            if count:
                batch = decode_record_rows(
                    transport.read_lines(count, RECORD_MIN_LENGTH, record_rest))
                self._check_continuity(batch[0], batch[-len(RECORD_FIELDS)])
                values += batch
            if remaining == 0:
                break
        rows = np.array(values, dtype=float).reshape(-1, len(RECORD_FIELDS))
        t_s, angle_deg, torque_mnm, gap_mm = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 4]
        force_n = rows[:, 3].copy()  # the only column used as it is: its own array
        # The same operations as one point at a time (math.radians is x * (pi / 180)).
        angle = np.radians(angle_deg)
        # 0-d array operands: the same float64 operations, faster than with Python floats.
        return StreamBlock(np.array(t0) + t_s, angle, angle * np.array(self._config.arm),
                           torque_mnm * _MILLI, force_n, gap_mm * _MILLI)

    def _check_continuity(self, first: float, last: float) -> None:
        """StreamOverflow if the batch's first record is not the one after the last read."""
        interval, previous = self._stream_interval, self._stream_last
        self._stream_last = last
        if interval > 0 and first - previous > GAP_TOLERANCE * interval:
            self._loss_reported = True
            lost = round((first - previous) / interval) - 1
            raise StreamOverflow(
                f"MCR 501: stream buffer overflowed: about {lost} points lost between "
                f"t = {previous:.3f} s and {first:.3f} s after the stream start "
                f"(records every {interval:g} s); the instrument was not read often enough")

    @guarded
    def stop_stream(self) -> None:
        """Stop recording; StreamOverflow if the instrument flags points lost since the last
        read (its overflow flag, cleared by the stop, is read first)."""
        overflowed = self._status().overflow
        self._transact("stop_stream")
        self._stream_t0 = None
        if overflowed and not self._loss_reported:
            raise StreamOverflow("MCR 501: stream buffer overflowed (status flag): points "
                                 "recorded since the last read were lost")

    def close(self) -> None:
        """Stop the arm if it may be turning, then release the transport; idempotent."""
        if self._link is None:
            return
        try:
            if self._maybe_rotating:
                self._emergency_stop()
        except InstrumentError as exc:
            log.error("MCR 501: stop on close failed: %s", exc)
        finally:
            self._release()

    def _release(self) -> None:
        link, self._link = self._link, None
        if link is not None:
            link.close()
