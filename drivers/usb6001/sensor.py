"""The load-cell force input through an NI USB-6001 and the official ``nidaqmx`` API.

The same class drives a local device (NI-DAQmx installed) or a device behind an NI gRPC
Device Server, real or simulated: only the ``grpc_options`` differ. Hardware-timed continuous
sampling; blocks are read with the stream reader into preallocated arrays, timestamped on the
injected clock from the sample index (sample k at start + k / rate), converted to newtons
through the calibration chain and the tare. The constructor does no I/O; ``open()`` (or
``with``) creates the task (ADR 0050).

Over gRPC every call has a deadline (``call_timeout``, plus a read's own timeout) so a frozen
server is an InstrumentTimeout, not a hang (ADR 0060); the task is the named server session
``gelrig_<device>``, and a session left by a process that died is closed and made anew on
``open()`` (ADR 0061).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, suppress

import grpc
import nidaqmx
import numpy as np
from nidaqmx import SessionInitializationBehavior as Behavior
from nidaqmx.constants import AcquisitionType, TerminalConfiguration
from nidaqmx.stream_readers import AnalogSingleChannelReader
from numpy.typing import ArrayLike

from gelrig.drivers.usb6001.config import MIN_RATE, RANGE_VOLTS, Usb6001Config
from gelrig.drivers.usb6001.deadline import DeadlineInterceptor, with_deadlines
from gelrig.drivers.usb6001.errors import NIDAQMX_ERRORS, SAMPLES_NOT_YET_AVAILABLE, translate
from gelrig.instrument.contracts.loadcell import (
    AcquisitionTimeoutError,
    ForceBlock,
    ForceOverRangeError,
    LoadCellChain,
)
from gelrig.instrument.contracts.stop_first import guarded, stop_on_fault
from gelrig.instrument.core import wire
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import (
    ConfigError,
    Disconnected,
    FramingError,
    GelrigError,
    InstrumentError,
    InstrumentTimeout,
)
from gelrig.instrument.core.identity import Identity
from gelrig.instrument.core.timebase import SampleClock

log = logging.getLogger(__name__)

#: Least run-clock time (s) between two queries of the samples waiting after a read (each is
#: a call to the device; a few per 5 s bin of the drift's envelope are enough).
ARRIVAL_QUERY_S = 0.5
#: Fallback device limit (S/s aggregate) if the device does not report its maximum rate.
DEFAULT_MAX_RATE = 20_000.0
_TERMINALS = {"RSE": TerminalConfiguration.RSE, "DIFF": TerminalConfiguration.DIFF}


def grpc_target(address: str) -> str | None:
    """The gRPC ``host:port`` of ``address`` ("grpc://host:port"), or None for "local".

    Checks the form only (no I/O): ConfigError for anything else.
    """
    text = address.strip()
    if text.lower() in ("", "local"):
        return None
    target = text[len("grpc://"):] if text.lower().startswith("grpc://") else text
    if ":" not in target:
        raise ConfigError("address", address, "allowed: local, or grpc://HOST:PORT")
    return target


def session_name(device: str) -> str:
    """gelrig's named server session (and DAQmx task) for ``device``: ``gelrig_<device>``."""
    return f"gelrig_{device}"


def grpc_options_for(address: str) -> tuple[nidaqmx.GrpcSessionOptions | None, grpc.Channel | None]:
    """Session options for ``address``: "local" (NI-DAQmx here) or "grpc://host:port".

    Returns the options and the channel the caller then owns (None for local).
    """
    target = grpc_target(address)
    if target is None:
        return None, None
    channel = grpc.insecure_channel(target, options=CHANNEL_OPTIONS)
    return nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name=""), channel


#: Each driver's channel keeps its own connections: grpc shares subchannels between channels
#: to one address by default, so a driver opened after a lost link would inherit the old
#: channel's reconnect back-off and fail at once with "unreachable".
CHANNEL_OPTIONS = (("grpc.use_local_subchannel_pool", 1),)


class Usb6001ForceSensor:
    """A :class:`~gelrig.instrument.contracts.loadcell.ForceSensor` on one USB-6001 analog input.

    ``address`` is "local" (NI-DAQmx on this computer), "grpc://host:port" (an NI gRPC Device
    Server, real or simulated; the channel is made by ``open()`` and closed by ``close()``),
    or ready ``GrpcSessionOptions`` whose channel the caller keeps. Constructing checks the
    address's form only; ``open()`` creates the DAQmx task and the voltage channel (min -10 V,
    max +10 V, passed explicitly), so a missing driver or device fails there with
    DaqDriverNotFoundError / DaqDeviceNotFoundError.
    """

    def __init__(
        self,
        address: str | nidaqmx.GrpcSessionOptions | None,
        config: Usb6001Config,
        chain: LoadCellChain,
        clock: Clock,
    ):
        self.config = config
        self.chain = chain
        self.clock = clock
        if isinstance(address, str):
            self._target = grpc_target(address)
            self._grpc: nidaqmx.GrpcSessionOptions | None = None
        else:
            self._target, self._grpc = None, address
        self._owned_channel: grpc.Channel | None = None
        self._deadlines = DeadlineInterceptor(config.call_timeout)
        given_name = self._grpc.session_name if self._grpc is not None else ""
        self.session = given_name or session_name(config.device)
        self.reclaimed = False  # open() took over a session a dead process left
        self._zero = chain.offset
        self._rate = 0.0
        self._running = False
        #: how sample indices map onto the run's clock (a new one per start)
        self.sample_clock = SampleClock(1.0, 0.0, 0.0)
        self._last_arrival_query = -math.inf
        self._index = 0
        self._task: nidaqmx.Task | None = None
        self._product = ""
        self._serial = 0

    # -- lifecycle -------------------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        return self._task is not None

    def open(self) -> Usb6001ForceSensor:
        """Create the task and its channel, and read the device's identity; returns self.

        A no-op if already open; on failure nothing is left open.
        """
        if self._task is not None:
            return self
        channel: grpc.Channel | None = None
        if self._target is not None:
            self._owned_channel = channel = grpc.insecure_channel(self._target,
                                                                  options=CHANNEL_OPTIONS)
        elif self._grpc is not None:
            channel = self._grpc.grpc_channel
        # recorded or replayed while a wire log is active (issue 30)
        channel = wire.grpc_channel("usb6001", self.clock, channel)
        try:
            # One budget for the whole open: nidaqmx probes the server's version three times
            # and swallows the failures, so per-call deadlines alone would add up.
            with self._deadlines.budget(2 * self.config.call_timeout):
                self._task = self._create_task(channel)
        except BaseException:
            self._close_channel()
            raise
        self._reader = AnalogSingleChannelReader(self._task.in_stream)
        # One channel, arrays sized here: skip the per-read channel-count query (an RPC).
        self._reader.verify_array_shape = False
        return self

    @property
    def server(self) -> str | None:
        """host:port of the NI gRPC Device Server, None for local NI-DAQmx (for messages)."""
        if self._target is not None:
            return self._target
        return None if self._grpc is None else "the given gRPC channel"

    def _options(self, channel: grpc.Channel, behavior: Behavior) -> nidaqmx.GrpcSessionOptions:
        kwargs = {} if self._grpc is None else {"api_key": self._grpc.api_key}
        return nidaqmx.GrpcSessionOptions(with_deadlines(channel, self._deadlines),
                                          self.session, initialization_behavior=behavior,
                                          **kwargs)

    def _new_task(self, channel: grpc.Channel | None) -> nidaqmx.Task:
        """The task: local, or gelrig's server session, reclaimed if a dead process left it.

        AUTO attaches to an existing session of that name; nidaqmx then marks the task as
        not to be closed by us (``_close_on_exit`` false). Such a session belongs to no live
        gelrig of this rig (one process per rig), so it is closed (stopping its acquisition,
        releasing the device) and a new one initialised.
        """
        if channel is None:
            return nidaqmx.Task()
        task = nidaqmx.Task(self.session, grpc_options=self._options(channel, Behavior.AUTO))
        if getattr(task, "_close_on_exit", True):
            return task
        log.warning("USB-6001 %s: reclaiming session %r on %s left by a process that ended "
                    "without closing it", self.config.device, self.session, self.server)
        task.close()
        self.reclaimed = True
        return nidaqmx.Task(self.session, grpc_options=self._options(
            channel, Behavior.INITIALIZE_SERVER_SESSION))

    def _create_task(self, channel: grpc.Channel | None) -> nidaqmx.Task:
        config = self.config
        with self._errors():
            task = self._new_task(channel)
            try:
                task.ai_channels.add_ai_voltage_chan(
                    config.physical_channel,
                    terminal_config=_TERMINALS[config.terminal],
                    min_val=-RANGE_VOLTS,
                    max_val=RANGE_VOLTS,
                )
                device = task.devices[0]
                self._product = str(device.product_type)
                self._serial = int(device.serial_num)
            except BaseException:
                with suppress(*NIDAQMX_ERRORS):
                    task.close()
                raise
        return task

    def _close_channel(self) -> None:
        if self._owned_channel is not None:
            self._owned_channel.close()
            self._owned_channel = None

    def __enter__(self) -> Usb6001ForceSensor:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _guard(self) -> AbstractContextManager[None]:
        """Stop the acquisition on a fault that leaves the sample count unknown.

        There is no motion to stop. A read cut short by Ctrl-C (or an unexpected error) may
        have consumed samples that were never counted, so later timestamps would be wrong:
        the task is stopped and the next ``start()`` counts afresh. The driver's typed errors
        are spared: they account for every sample (a timeout or over-range block is attached)
        and the caller may read on or restart, as the ForceSensor contract allows.
        """
        return stop_on_fault(self._abort, needed=lambda: self._task is not None,
                             spare=(GelrigError,), what=f"USB-6001 {self.config.device}")

    def _abort(self) -> None:
        self._running = False
        if self._task is not None:
            with self._errors():
                self._task.stop()

    @contextmanager
    def _errors(self) -> Iterator[None]:
        try:
            yield
        except NIDAQMX_ERRORS as exc:
            raise self._translate(exc) from exc

    def _translate(self, exc: Exception) -> GelrigError:
        return translate(exc, self.config.device, self.server, self.session)

    @property
    def task(self) -> nidaqmx.Task:
        if self._task is None:
            raise InstrumentError(
                f"USB-6001 {self.config.device}: the sensor is closed (or not yet open)")
        return self._task

    @property
    def rate(self) -> float:
        return self._rate

    @property
    def zero_volts(self) -> float:
        """Input voltage (V) taken as zero force: the chain's offset until a tare."""
        return self._zero

    def identify(self) -> Identity:
        """The device read at ``open()``; ``extra`` keeps run.json's former force keys."""
        if self._task is None:
            raise InstrumentError(f"USB-6001 {self.config.device}: not open (call open())")
        return Identity("NI", self._product, f"{self._serial:X}", extra={
            "instrument": f"NI {self._product}",
            "device": self.config.device,
            "channel": self.config.physical_channel,
            "terminal": self.config.terminal,
            "transport": "local NI-DAQmx" if self.server is None else "grpc",
        })

    def max_rate(self) -> float:
        """The device's sample-rate limit for this task (S/s)."""
        with self._errors():
            try:
                return float(self.task.timing.samp_clk_max_rate)
            except nidaqmx.errors.DaqError:
                return DEFAULT_MAX_RATE

    @guarded
    def start(self, rate_hz: float) -> None:
        """Start continuous hardware-timed sampling at ``rate_hz``."""
        limit = self.max_rate()
        if not (math.isfinite(rate_hz) and MIN_RATE <= rate_hz <= limit):
            raise ConfigError("rate", rate_hz, f"allowed [{MIN_RATE:g}, {limit:g}] Hz")
        if self._running:
            self.stop()
        buffer = max(2, math.ceil(rate_hz * self.config.buffer_seconds))
        with self._errors():
            self.task.timing.cfg_samp_clk_timing(
                rate_hz, sample_mode=AcquisitionType.CONTINUOUS, samps_per_chan=buffer
            )
            lo = self.clock.now()
            self.task.start()
            self.sample_clock = SampleClock(rate_hz, lo, self.clock.now())
        self._rate = float(rate_hz)
        self._index = 0
        self._running = True

    @guarded
    def read_block(self, n: int | None = None, timeout: float | None = None) -> ForceBlock:
        """The next ``n`` samples (None: all available now), waiting up to ``timeout`` (s).

        The default timeout is the block's duration plus ``config.read_margin``; over gRPC
        the call's deadline is that plus ``config.call_timeout`` (InstrumentTimeout after it).
        """
        if not self._running:
            raise InstrumentError(f"USB-6001 {self.config.device}: read before start()")
        with self._errors():
            if n is None:
                n = int(self.task.in_stream.avail_samp_per_chan)
        if n < 0:
            raise ValueError(f"cannot read {n} samples")
        if timeout is None:
            timeout = n / self._rate + self.config.read_margin
        if not (math.isfinite(timeout) and timeout >= 0):
            raise ValueError(f"read timeout must be a finite number of seconds, got {timeout}")
        data = np.empty(n)
        try:
            if n:
                self._reader.read_many_sample(data, n, timeout=timeout)
        except nidaqmx.errors.DaqReadError as exc:
            if exc.error_code != SAMPLES_NOT_YET_AVAILABLE:
                raise self._translate(exc) from exc
            got = exc.samps_per_chan_read
            block = self._block(data[:got])
            raise AcquisitionTimeoutError(
                f"USB-6001 {self.config.device}: {got} of {n} samples arrived within "
                f"{timeout:g} s", block) from exc
        except NIDAQMX_ERRORS as exc:
            raise self._translate(exc) from exc
        block = self._block(data)
        if n and self.clock.now() - self._last_arrival_query >= ARRIVAL_QUERY_S:
            self._note_arrival()
        if block.any_over_range and self.config.on_over_range == "raise":
            bad = np.flatnonzero(block.over_range)
            raise ForceOverRangeError(
                f"USB-6001 {self.config.device}: {bad.size} of {n} samples beyond "
                f"+-{self.config.over_range_volts:g} V (first at t = {block.t[bad[0]]:.6g} s, "
                f"{block.volts[bad[0]]:+.4f} V): the input clipped or is out of range", block)
        return block

    def _block(self, volts: np.ndarray) -> ForceBlock:
        """Timestamp and convert samples that were just read; advance the sample index.

        Sample k is at ``t0 + k / rate`` on the sample clock, mapped onto the run's clock
        (:class:`SampleClock`: the start's window, the drift from the blocks' arrivals)."""
        k = self._index + np.arange(volts.size, dtype=float)
        self._index += volts.size
        return ForceBlock(
            t=self.sample_clock.times(k),
            force=self.chain.newtons(volts, self._zero),
            volts=volts,
            over_range=np.abs(volts) > self.config.over_range_volts,
        )

    def _note_arrival(self) -> None:
        """Tell the sample clock how far the samples had arrived just now: the last sample
        read plus those already waiting (the rest of its USB transfer), by the time the
        count came back; the earliest such arrivals give the sample clock's drift."""
        with self._errors():
            waiting = int(self.task.in_stream.avail_samp_per_chan)
        now = self._last_arrival_query = self.clock.now()
        self.sample_clock.arrived(self._index - 1 + waiting, now)

    def tare(self, duration: float = 1.0) -> float:
        """Zero on the mean input over ``duration`` (s) of samples; return the removed force (N).

        Needs a running acquisition and no load on the cell.
        """
        if not self._running:
            raise InstrumentError(f"USB-6001 {self.config.device}: tare before start()")
        block = self.read_block(max(1, round(duration * self._rate)))
        return self.zero_on(block.volts)

    def zero_on(self, volts: ArrayLike) -> float:
        """Zero on the mean of input volts already read; return the removed force (N)."""
        v = np.asarray(volts, dtype=float)
        if v.size == 0:
            raise InstrumentError(f"USB-6001 {self.config.device}: tare needs samples")
        self._zero = float(np.mean(v))
        return (self._zero - self.chain.offset) / self.chain.sensitivity

    def stop(self) -> None:
        if self._running and self._task is not None:
            self._running = False
            with self._errors():
                self._task.stop()

    def close(self) -> None:
        """Stop, release the task, and close a gRPC channel this sensor opened; idempotent.

        Bounded by one ``call_timeout`` in all (a frozen server costs one deadline). A server
        that is gone or frozen is logged, not raised: the task is released here either way,
        and the next ``open()`` on that server reclaims its session (ADR 0061).
        """
        try:
            with self._deadlines.budget(self.config.call_timeout):
                try:
                    self.stop()
                finally:
                    task, self._task = self._task, None
                    try:
                        if task is not None:
                            with self._errors():
                                task.close()
                    finally:
                        self._close_channel()
        except (Disconnected, InstrumentTimeout, FramingError) as exc:
            log.warning("USB-6001 %s: closed without the server's answer: %s",
                        self.config.device, exc)
