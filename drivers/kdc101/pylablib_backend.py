"""The same ``Stage`` on pylablib's ``KinesisMotor``, for labs that already trust pylablib.

Optional: needs the ``pylablib`` extra (pylablib-lightweight, plus numba, which pylablib's
Thorlabs package imports). pylablib does the APT talking; this adapter converts units, checks
software limits before anything is sent, waits on the injected clock, maps pylablib's errors to
ours, and sends a stop on any fault while moving (Ctrl-C included). Like ``KDC101``, the
constructor does no I/O and ``open()`` connects (ADR 0050). Moves longer than
``StageConfig.motion_bound_s`` and velocity moves go out as bounded segments (absolute
targets) renewed by every later call, as in ``KDC101`` (ADR 0201).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from typing import Any

from gelrig.drivers.kdc101 import payloads as pl
from gelrig.drivers.kdc101.apt import CHANNEL, MsgId
from gelrig.drivers.kdc101.driver import stage_identity
from gelrig.drivers.kdc101.segments import BoundedMove, SegmentPlan
from gelrig.instrument.contracts.stage import StageConfig, StageStatus
from gelrig.instrument.contracts.stop_first import stop_on_fault
from gelrig.instrument.core.clock import Clock, RealClock
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    InstrumentError,
    InstrumentTimeout,
)
from gelrig.instrument.core.identity import Identity


def load_kinesis() -> Any:
    """pylablib's kinesis module, imported on first use; InstrumentError if not installed."""
    try:
        return importlib.import_module("pylablib.devices.Thorlabs.kinesis")
    except ImportError as exc:
        raise InstrumentError(
            f"the pylablib backend needs the 'pylablib' extra (pylablib-lightweight and numba): "
            f"{exc}") from exc


def pylablib_conn(port: str) -> Any:
    """pylablib's connection spec: pyserial URLs must be forced onto its serial backend."""
    return ("serial", port) if "://" in port else port


class PylablibKDC101:
    """A KDC101 stage driven through ``pylablib.devices.Thorlabs.KinesisMotor`` (a Stage)."""

    def __init__(self, port: str, config: StageConfig | None = None, clock: Clock | None = None,
                 *, timeout_s: float | None = None):
        self.config = config or StageConfig()
        self.clock: Clock = clock or RealClock()
        self.address = port
        self._timeout_s = timeout_s
        self._maybe_moving = False
        self._segment: BoundedMove | None = None  # the segmented move in progress (ADR 0201)
        self._renewing = False
        self.renewals = 0
        self._motor: Any = None
        self._errors: tuple[type[Exception], ...] = ()  # pylablib's, known once loaded
        self.identity: Identity | None = None

    # ---- lifecycle --------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self._motor is not None

    @property
    def motor(self) -> Any:
        """pylablib's KinesisMotor; Disconnected before ``open()`` or after ``close()``."""
        if self._motor is None:
            raise Disconnected(f"KDC101 (pylablib) at {self.address}: not open (call open())")
        return self._motor

    def open(self) -> PylablibKDC101:
        """Connect through pylablib, identify and set the configured velocity; returns self."""
        if self._motor is not None:
            return self
        kinesis = load_kinesis()
        self._errors = (kinesis.ThorlabsError,)
        self._timeout_cls = kinesis.ThorlabsTimeoutError
        self._backend_cls = kinesis.ThorlabsBackendError
        c = self.config
        scale = (c.counts_per_mm * 1e3, c.velocity_factor * 1e3, c.accel_factor * 1e3)
        with self._mapped():
            motor = kinesis.KinesisMotor(pylablib_conn(self.address), scale=scale)
        self._motor = motor
        try:
            with self._mapped():
                motor.instr.set_timeout(self._timeout_s or c.reply_timeout_s)
            self.identity = self.identify()
            self.set_velocity(c.max_velocity_m_s, c.acceleration_m_s2)
        except BaseException:
            self.close()
            raise
        return self

    def __enter__(self) -> PylablibKDC101:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- errors and safety ------------------------------------------------------------
    @contextmanager
    def _mapped(self) -> Iterator[None]:
        """pylablib's exceptions -> ours; a stop first (any fault) if the stage may be moving."""
        with stop_on_fault(self._emergency_stop, needed=lambda: self._maybe_moving,
                           what=f"KDC101 (pylablib) at {self.address}"):
            try:
                if self._segment is not None and not self._renewing:
                    self._renew_segment()
                yield
            except self._errors as exc:
                raise self._translate(exc) from exc

    def _translate(self, exc: Exception) -> InstrumentError:
        text = f"KDC101 (pylablib) at {self.address}: {exc}"
        if isinstance(exc, self._timeout_cls) or "less than expected" in str(exc):
            return InstrumentTimeout(text)
        if isinstance(exc, self._backend_cls):
            return Disconnected(text)
        if "got 0x0080" in str(exc) or "got 0x0081" in str(exc):
            return DeviceErrorReply(text)
        return InstrumentError(text)

    def _emergency_stop(self) -> None:
        self._segment = None
        self.motor.send_comm(MsgId.MOT_MOVE_STOP, CHANNEL, pl.STOP_IMMEDIATE)

    # ---- Stage ------------------------------------------------------------------------
    def identify(self) -> Identity:
        with self._mapped():
            info = self.motor.get_device_info()
        if not str(info.model_no).startswith("KDC101"):
            raise InstrumentError(f"{self.address}: expected a KDC101, found {info.model_no!r}")
        return stage_identity(str(info.model_no), int(info.serial_no), str(info.fw_ver),
                              int(info.hw_ver), int(info.nchannels))

    def enable(self) -> None:
        with self._mapped():
            self.motor.send_comm(MsgId.MOD_SET_CHANENABLESTATE, CHANNEL, pl.CHAN_ENABLED)
            state = self.motor.query(MsgId.MOD_REQ_CHANENABLESTATE, CHANNEL)
        if state.param2 != pl.CHAN_ENABLED:
            raise InstrumentError(f"KDC101 (pylablib) at {self.address}: channel did not enable")

    def set_velocity(self, max_m_s: float, accel_m_s2: float) -> None:
        self.config.check_velocity(max_m_s, accel_m_s2)
        with self._mapped():
            self.motor.setup_velocity(acceleration=accel_m_s2, max_velocity=max_m_s)
        self.max_velocity_m_s, self.acceleration_m_s2 = max_m_s, accel_m_s2

    def home(self, wait: bool = True, timeout: float | None = None) -> None:
        self._segment = None
        with self._mapped():
            self._maybe_moving = True
            self.motor.home(sync=False, force=True)
        if wait:
            self.wait_until_stopped(timeout)
            if not self.status().homed:
                raise InstrumentError(f"KDC101 (pylablib) at {self.address}: homing failed")

    def move_to(self, position_m: float, wait: bool = True, timeout: float | None = None) -> None:
        self.config.check_position(position_m)
        with self._mapped():
            self._maybe_moving = True
            self._start_move(float(self.motor.get_position()), position_m)
        if wait:
            self.wait_until_stopped(timeout)

    def move_by(self, distance_m: float, wait: bool = True, timeout: float | None = None) -> None:
        start = self.position()
        self.config.check_position(start + distance_m)
        with self._mapped():
            self._maybe_moving = True
            if self._plan().fits(distance_m):
                self._segment = None
                self.motor.move_by(distance_m)
            else:
                self._start_move(start, start + distance_m)
        if wait:
            self.wait_until_stopped(timeout)

    def move_velocity(self, direction: int) -> None:
        """Run at the set velocity until ``stop``, at most to the software travel limit, as
        bounded segments (ADR 0201)."""
        if direction not in (1, -1):
            raise ValueError(f"direction must be +1 or -1, got {direction}")
        c = self.config
        end = c.max_position_m if direction > 0 else c.min_position_m
        with self._mapped():
            self._maybe_moving = True
            start = float(self.motor.get_position())
            if (end - start) * direction > 0:
                self._start_move(start, end)

    def keep_alive(self) -> None:
        """Renew the segmented move in progress if it is due (ADR 0201); else nothing."""
        if self._segment is not None:
            with self._mapped():
                pass  # entering renews a due segment

    # ---- bounded segments (ADR 0201) --------------------------------------------------
    def _plan(self) -> SegmentPlan:
        return SegmentPlan.of(self.max_velocity_m_s, self.acceleration_m_s2,
                              self.config.motion_bound_s)

    def _start_move(self, start: float, final: float) -> None:
        plan = self._plan()
        if plan.fits(final - start):
            self._segment = None
            self.motor.move_to(final)
            return
        move = BoundedMove(final, 1 if final > start else -1, plan.lookahead, plan, final,
                           self.clock.now())
        self._send_segment(move, move.next_target(start))

    def _send_segment(self, move: BoundedMove, target: float) -> None:
        self.motor.move_to(target)
        if target == move.final:
            self._segment = None
        else:
            move.target, move.renewed_at = target, self.clock.now()
            self._segment = move

    def _renew_segment(self) -> None:
        """The next segment if due; InstrumentError if so late that the stage may have
        slowed down (the move is abandoned, and the caller's guard stops the stage)."""
        move = self._segment
        now = self.clock.now()
        if move is None or not move.due(now):
            return
        if move.late(now):
            self._segment = None
            raise InstrumentError(
                f"KDC101 (pylablib) at {self.address}: a move segment was renewed "
                f"{now - move.renewed_at:.2f} s after the last (at most "
                f"{move.plan.late_after:.2f} s keeps the speed profile); the move is "
                "abandoned (ADR 0201)")
        self._renewing = True
        try:
            position = float(self.motor.get_position())
        finally:
            self._renewing = False
        if self._segment is not move:
            return  # a stop came in the meantime
        self.renewals += 1
        self._send_segment(move, move.next_target(position))

    def stop(self, immediate: bool = True) -> None:
        self._segment = None  # before anything: a stop never renews a segment
        with self._mapped():
            self.motor.stop(immediate=immediate, sync=False)
        if immediate:
            self.wait_until_stopped(self.config.reply_timeout_s)

    def position(self) -> float:
        with self._mapped():
            return float(self.motor.get_position())

    def status(self) -> StageStatus:
        with self._mapped():
            return pl.decode_status(int(self.motor.get_status_n()), self.config.direction)

    def is_moving(self) -> bool:
        return self.status().busy

    def wait_until_stopped(self, timeout: float | None = None) -> None:
        limit = self.config.move_timeout_s if timeout is None else timeout
        deadline = self.clock.now() + limit
        with self._mapped():
            while self.status().busy:
                if self.clock.now() >= deadline:
                    raise InstrumentTimeout(
                        f"KDC101 (pylablib) at {self.address}: still moving after {limit} s")
                self.clock.sleep(self.config.poll_interval_s)
            self._maybe_moving = False

    def close(self) -> None:
        """Release pylablib's connection (does not move the stage); idempotent."""
        motor, self._motor = self._motor, None
        if motor is not None:
            with suppress(Exception):
                motor.close()
