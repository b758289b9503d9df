"""The simulated NI USB-6001's analog input: tasks, channels, sample clock, buffer and ADC.

Samples of a running task exist at ``t0 + k / rate`` on the shared clock (t0 = start time).
They are computed only when read (from the channels' signal sources), but they accrue with
the clock whoever advances it: if the unread count exceeds the buffer, the next read fails
with DAQmx error -200279 as the device does, and keeps failing until the task is restarted.
A read of samples not yet acquired waits on the clock for the last of them (instant on a
virtual clock) up to the read timeout, draining the buffer while it waits, so one read may be
longer than the buffer (docs/decisions/0011).

Errors are :class:`DaqmxError` carrying the DAQmx error code; the gRPC layer turns them into
what the official client raises.
"""

from __future__ import annotations

import math
import re
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gelrig.instrument.core.clock import Clock
from gelrig.instrument.physics.contact import FloatArray
from gelrig.simulators.usb6001.signals import ConstantSignal, SignalSource

# DAQmx constants (nidaqmx.constants) used on the wire.
RSE, DIFF, NRSE, PSEUDO_DIFF, DEFAULT_TERMINAL = 10083, 10106, 10078, 12529, -1
VOLTS = 10348
FROM_CUSTOM_SCALE = 10065
CONTINUOUS, FINITE = 10123, 10178
GROUP_BY_CHANNEL, GROUP_BY_SCAN_NUMBER = 0, 1
MEAS_VOLTAGE = 10322
READ_ALL_AVAILABLE = -1
# Read.RelativeTo and Read.OverWrite values.
FIRST_SAMPLE, CURRENT_READ_POSITION, REFERENCE_TRIGGER = 10424, 10425, 10426
FIRST_PRETRIGGER_SAMPLE, MOST_RECENT_SAMPLE = 10427, 10428
OVERWRITE_UNREAD, DO_NOT_OVERWRITE_UNREAD = 10252, 10159

# DAQmx error codes (nidaqmx.error_codes.DAQmxErrors) the simulator raises.
SAMPLES_NO_LONGER_AVAILABLE = -200279
SAMPLES_NOT_YET_AVAILABLE = -200284
SAMPLES_WILL_NEVER_BE_AVAILABLE = -200278
INVALID_DEVICE_ID = -200220
PHYSICAL_CHAN_DOES_NOT_EXIST = -200170
INVALID_ATTRIBUTE_VALUE = -200077
MIN_NOT_LESS_THAN_MAX = -200082
INVALID_TASK = -200088
DUPLICATE_TASK = -200089
ATTR_NOT_SUPPORTED = -200197
READ_BUFFER_TOO_SMALL = -200229
CANNOT_READ_TASK_NOT_RUNNING = -200473
NEGATIVE_READ_SAMPLE_NUMBER = -200277
NO_REF_TRIG_CONFIGURED = -200282
WAIT_UNTIL_DONE_DOES_NOT_INDICATE_DONE = -200560
ATTRIBUTE_NOT_SUPPORTED_IN_TASK_CONTEXT = -200452
FUNCTION_NOT_SUPPORTED_FOR_DEVICE = -209876
EVERY_N_SAMPS_TRANSFERRED_EVENT_NOT_SUPPORTED = -200980
CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING = -200479
CHAN_ALREADY_IN_TASK = -200489
NO_CHANS_IN_TASK = -200478
RESOURCE_RESERVED = -50103
TRANSFER_ABORTED = -50405

ERROR_TEXT = {
    SAMPLES_NO_LONGER_AVAILABLE: (
        "The application is not able to keep up with the hardware acquisition.\n"
        "Increasing the buffer size, reading the data more frequently, or specifying a fixed "
        "number of samples to read instead of reading all available samples might correct "
        "the problem."
    ),
    SAMPLES_NOT_YET_AVAILABLE: (
        "Some or all of the samples requested have not yet been acquired."
    ),
    SAMPLES_WILL_NEVER_BE_AVAILABLE: (
        "Attempted to read samples that will never be available: the finite acquisition "
        "ends before them."
    ),
    INVALID_DEVICE_ID: "Device identifier is invalid.",
    PHYSICAL_CHAN_DOES_NOT_EXIST: "Physical channel specified does not exist on this device.",
    INVALID_ATTRIBUTE_VALUE: "Requested value is not a supported value for this property.",
    MIN_NOT_LESS_THAN_MAX: "Minimum is not less than maximum.",
    INVALID_TASK: "Task specified is invalid or does not exist.",
    DUPLICATE_TASK: "Task cannot be created because a task with this name already exists.",
    ATTR_NOT_SUPPORTED: "Specified property is not supported by the device or is not "
    "applicable to the task.",
    READ_BUFFER_TOO_SMALL: "Buffer is too small to fit read data.",
    CANNOT_READ_TASK_NOT_RUNNING: "Read cannot be performed because the task is not running "
    "and Read.AutoStart is false: start the task before reading, or set auto_start to True.",
    NEGATIVE_READ_SAMPLE_NUMBER: "The sample number to read (position plus offset) is negative.",
    NO_REF_TRIG_CONFIGURED: "Reading relative to the reference trigger or the first "
    "pretrigger sample needs a reference trigger, and none is configured.",
    WAIT_UNTIL_DONE_DOES_NOT_INDICATE_DONE: "Wait Until Done did not indicate that all samples "
    "were acquired within the specified timeout.",
    ATTRIBUTE_NOT_SUPPORTED_IN_TASK_CONTEXT: "Specified property is not supported by the "
    "device or is not applicable to the task.",
    FUNCTION_NOT_SUPPORTED_FOR_DEVICE: "The function is not supported by this device.",
    EVERY_N_SAMPS_TRANSFERRED_EVENT_NOT_SUPPORTED: "Every N Samples Transferred from Buffer "
    "event is not supported for input tasks: use Every N Samples Acquired into Buffer.",
    CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING: "Specified operation cannot be performed while the "
    "task is running.",
    CHAN_ALREADY_IN_TASK: "Specified channel cannot be added to the task, because a channel "
    "with the same name is already in the task.",
    NO_CHANS_IN_TASK: "Specified operation cannot be performed when there are no channels "
    "in the task.",
    RESOURCE_RESERVED: "The specified resource is reserved. The operation could not be "
    "completed as specified.",
    TRANSFER_ABORTED: "Transfer aborted: the task was stopped while a read was waiting.",
}


class InvalidRequest(ValueError):
    """A request whose fields cannot be converted (a malformed waveform, say): the gRPC
    server answers INVALID_ARGUMENT, as NI's grpc-device server does for a value it cannot
    convert, before the device sees it."""


class DaqmxError(Exception):
    """A DAQmx error of the simulated device: code, message, samples read before it."""

    def __init__(self, code: int, detail: str = "", samps_read: int | None = None,
                 data: FloatArray | None = None):
        self.code = code
        self.samps_read = samps_read
        self.data = data
        text = ERROR_TEXT.get(code, "DAQmx error.")
        super().__init__(f"{text}\n{detail}".rstrip() + f"\n\nStatus Code: {code}")


@dataclass(frozen=True)
class DeviceSpec:
    """What a USB-6001's AI is (instruments.md); the aggregate rate is UNVERIFIED."""

    name: str = "Dev1"
    product_type: str = "USB-6001"
    serial: int = 0x01B3C4D5
    rse_channels: int = 8
    diff_channels: int = 4
    resolution_bits: int = 14
    range_volts: float = 10.0
    clip_volts: float = 10.5
    max_aggregate_rate: float = 20_000.0
    #: how its sample clock and its USB transfers meet the host's clock (default: ideal)
    timing: DaqTiming = field(default_factory=lambda: DaqTiming())

    @property
    def lsb(self) -> float:
        """One ADC code (V): the +-10 V span over 2^bits codes."""
        return 2.0 * self.range_volts / 2**self.resolution_bits


@dataclass(frozen=True)
class DaqTiming:
    """How the simulated device's samples meet the host's clock (issue 24).

    ``drift_ppm``: its sample clock runs this much fast (+) or slow (-) against the host's
    (the USB-6001's timebase accuracy is +-100 ppm: UNVERIFIED, NI spec sheet); sample k is
    converted at ``t0 + k / (rate (1 + drift))``. ``transfer``: samples per USB transfer; a
    transfer reaches the host ``latency`` s after its last sample's conversion, plus a jitter
    uniform in [0, ``jitter``] s per transfer (seeded by ``seed``; transfers stay in order).
    The default is the ideal device (no drift, every sample at once). :data:`DOCUMENTED` holds
    the values the documents suggest.
    """

    drift_ppm: float = 0.0
    latency: float = 0.0
    jitter: float = 0.0
    transfer: int = 1
    seed: int = 0

    def __post_init__(self) -> None:
        if not (abs(self.drift_ppm) < 1e4 and self.latency >= 0 and self.jitter >= 0
                and self.transfer >= 1):
            raise ValueError(f"impossible DAQ timing {self}")

    def jitter_of(self, j: int) -> float:
        """The extra latency (s) of transfer ``j``: a fixed pseudo-random draw."""
        if self.jitter <= 0:
            return 0.0
        h = (j * 0x9E3779B97F4A7C15 + self.seed * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
        h ^= h >> 31
        h = (h * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
        h ^= h >> 29
        return self.jitter * (h / 2.0**64)


#: The USB-6001's timing as documented or assumed: 100 ppm timebase accuracy (NI spec sheet,
#: UNVERIFIED), USB transfers of 32 samples (UNVERIFIED) arriving 1 ms after the last
#: sample (a USB full-speed frame; UNVERIFIED) with up to 2 ms of host-side jitter
#: (UNVERIFIED).
DOCUMENTED = DaqTiming(drift_ppm=100.0, latency=1e-3, jitter=2e-3, transfer=32)


def default_buffer_size(rate: float) -> int:
    """DAQmx's default input buffer (samples per channel) for a continuous task at ``rate``."""
    if rate <= 100:
        return 1_000
    if rate <= 10_000:
        return 10_000
    if rate <= 1_000_000:
        return 100_000
    return 1_000_000


@dataclass
class AIChannel:
    """One voltage channel of a task."""

    name: str
    physical: str  # "ai0"
    terminal: int
    min_val: float
    max_val: float
    description: str = ""


@dataclass
class SimTask:
    """A DAQmx task on the simulated device.

    Without a sample clock (``timing_set`` false) the task is on demand: each read takes
    fresh samples now. ``auto_started``: a read started it and stops it when done with it.
    """

    name: str
    channels: list[AIChannel] = field(default_factory=list)
    rate: float = 1000.0
    sample_mode: int = FINITE
    samps_per_chan: int = 1000
    timing_set: bool = False
    running: bool = False
    auto_started: bool = False
    t0: float = 0.0
    read_pos: int = 0
    overflowed: bool = False
    buffer_size: int = 1000
    buffer_request: int | None = None
    # Read properties (in_stream).
    auto_start: bool = True
    read_all_avail: bool = False
    relative_to: int = CURRENT_READ_POSITION
    offset: int = 0
    overwrite: int = DO_NOT_OVERWRITE_UNREAD
    # Samples computed so far (sources are stateful, so each is computed once).
    gen_pos: int = 0
    hist: FloatArray = field(default_factory=lambda: np.empty((0, 0)))
    hist_start: int = 0
    # The storage ``hist`` is a view of (room to append without copying what is kept).
    hist_buf: FloatArray = field(default_factory=lambda: np.empty((0, 0)))
    hist_off: int = 0
    on_demand_next: float = -math.inf
    #: a start trigger: maps the start time to the first sample's (inf: no edge yet), set by
    #: gelrig.simulators.usb6001.triggers (docs/decisions/0290)
    start_gate: Callable[[float], float] | None = None

    #: how samples meet the host's clock (the device's :class:`DaqTiming`)
    timing: DaqTiming = field(default_factory=lambda: DaqTiming())

    @property
    def true_rate(self) -> float:
        """The rate the sample clock really runs at, on the host's clock (its drift)."""
        return self.rate * (1.0 + 1e-6 * self.timing.drift_ppm)

    def converted(self, now: float) -> int:
        """Samples converted by ``now`` (sample k at t0 + k / true_rate)."""
        if not self.running or not self.timing_set or now < self.t0:
            return 0
        n = math.floor((now - self.t0) * self.true_rate + 1e-6) + 1
        return min(n, self.samps_per_chan) if self.sample_mode == FINITE else n

    def delivered_at(self, k: int) -> float:
        """When sample ``k`` reaches the host: its transfer's last conversion, plus latency
        and jitter (the last transfer of a finite task may be short)."""
        timing = self.timing
        j = k // timing.transfer
        last = (j + 1) * timing.transfer - 1
        if self.sample_mode == FINITE:
            last = min(last, self.samps_per_chan - 1)
        base = self.t0 + last / self.true_rate + timing.latency
        if timing.jitter <= 0:
            return base
        # in order: a transfer arrives no earlier than the one before it
        prev = self.t0 + (last - timing.transfer) / self.true_rate + timing.latency
        return max(base + timing.jitter_of(j), prev + timing.jitter_of(j - 1) if j else base)

    def acquired(self, now: float) -> int:
        """Samples per channel that have reached the host's buffer by ``now``."""
        n = self.converted(now)
        timing = self.timing
        if timing.transfer == 1 and timing.latency == 0 and timing.jitter == 0:
            return n
        n = self.converted(now - timing.latency)
        if not (self.sample_mode == FINITE and n >= self.samps_per_chan):
            n = n // timing.transfer * timing.transfer  # whole transfers only
        while n > 0 and self.delivered_at(n - 1) > now:
            n = (n - 1) // timing.transfer * timing.transfer  # back one transfer
        return n

    def done(self, now: float) -> bool:
        """DAQmx Is Task Done: not running, on demand, or a finite acquisition complete."""
        if not self.running or not self.timing_set:
            return True
        return self.sample_mode == FINITE and self.acquired(now) >= self.samps_per_chan


_CHAN = re.compile(r"^\s*/?(?P<dev>[^/\s]+)/ai(?P<a>\d+)(?::(?P<b>\d+))?\s*$", re.IGNORECASE)


class SimulatedUsb6001:
    """The analog input of one simulated USB-6001 on a shared clock.

    ``sources`` maps "ai0".."ai7" to signal sources (unwired inputs read 0 V plus noise).
    ``buffer_size`` (samples per channel) overrides DAQmx's buffer rule when given.
    Thread-safe: the gRPC server calls it from several threads.
    """

    def __init__(
        self,
        clock: Clock,
        sources: Mapping[str, SignalSource] | None = None,
        spec: DeviceSpec | None = None,
        buffer_size: int | None = None,
    ):
        self.clock = clock
        self.spec = spec or DeviceSpec()
        self.sources: dict[str, SignalSource] = {
            f"ai{i}": ConstantSignal(0.0, noise_rms=0.5e-3, seed=1000 + i)
            for i in range(self.spec.rse_channels)
        }
        for key, source in (sources or {}).items():
            if key not in self.sources:
                raise ValueError(f"no input {key!r} on a {self.spec.product_type}")
            self.sources[key] = source
        if buffer_size is not None and buffer_size < 2:
            raise ValueError(f"buffer_size must be >= 2 samples, got {buffer_size}")
        self.buffer_override = buffer_size
        self._tasks: dict[str, SimTask] = {}
        self._lock = threading.Lock()
        self._unnamed = 0

    # --- tasks -----------------------------------------------------------------------------

    def create_task(self, name: str) -> str:
        with self._lock:
            if not name:
                name = f"_unnamedTask<{self._unnamed}>"
                self._unnamed += 1
            if name in self._tasks:
                raise DaqmxError(DUPLICATE_TASK, f"Task Name: {name}")
            self._tasks[name] = SimTask(name)
            return name

    def has_task(self, name: str) -> bool:
        with self._lock:
            return name in self._tasks

    def task(self, name: str) -> SimTask:
        try:
            return self._tasks[name]
        except KeyError:
            raise DaqmxError(INVALID_TASK, f"Task Name: {name}") from None

    def clear_task(self, name: str) -> None:
        with self._lock:
            self.task(name).running = False
            del self._tasks[name]

    def add_voltage_channel(
        self, task_name: str, physical: str, assigned: str, terminal: int,
        min_val: float, max_val: float, units: int,
    ) -> None:
        with self._lock:
            task = self.task(task_name)
            if task.running:
                raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
            default = terminal == DEFAULT_TERMINAL
            terminal = RSE if default else terminal
            if terminal not in (RSE, DIFF):
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: AI.TermCfg\nRequested Value: {terminal}\n"
                                 f"Possible Values: RSE ({RSE}), Differential ({DIFF})")
            if units != VOLTS:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: AI.Voltage.Units\nRequested Value: {units}\n"
                                 "This simulator supports volts only.")
            if not min_val < max_val:
                raise DaqmxError(MIN_NOT_LESS_THAN_MAX, f"Minimum: {min_val}\nMaximum: {max_val}")
            r = self.spec.range_volts
            if min_val < -r or max_val > r:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: AI.Min / AI.Max\nRequested: {min_val}..{max_val}\n"
                                 f"The {self.spec.product_type} has one range: -{r:g} to {r:g} V")
            physicals = self._parse_channels(physical, terminal)
            names = [p.strip() for p in assigned.split(",")] if assigned else []
            if names and len(names) != len(physicals):
                names = [f"{assigned}{i}" for i in range(len(physicals))]
            new = [AIChannel(names[i] if names else full, short,
                             default_terminal(short) if default else terminal, min_val, max_val)
                   for i, (full, short) in enumerate(physicals)]
            add_named(task.channels, new)

    def check_device(self, name: str) -> None:
        """DAQmx device names are not case sensitive: "dev1" is "Dev1"."""
        if name.strip().lower() != self.spec.name.lower():
            raise DaqmxError(INVALID_DEVICE_ID, f"Device Specified: {name}\n"
                             f"Devices in System: {self.spec.name}")

    def _parse_channels(self, text: str, terminal: int) -> list[tuple[str, str]]:
        count = self.spec.rse_channels if terminal == RSE else self.spec.diff_channels
        dev = self.spec.name
        out: list[tuple[str, str]] = []
        for part in text.split(","):
            m = _CHAN.match(part)
            if m is None:
                raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST, f"Physical Channel: {part.strip()}")
            self.check_device(m["dev"])
            a = int(m["a"])
            b = int(m["b"]) if m["b"] is not None else a
            step = 1 if b >= a else -1
            for i in range(a, b + step, step):
                if i >= count:
                    raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST,
                                     f"Physical Channel: {dev}/ai{i}\nThe "
                                     f"{self.spec.product_type} has ai0..ai{count - 1} "
                                     f"{'RSE' if terminal == RSE else 'differential'}.")
                out.append((f"{dev}/ai{i}", f"ai{i}"))
        return out

    def cfg_timing(
        self, task_name: str, rate: float, sample_mode: int, samps_per_chan: int
    ) -> None:
        with self._lock:
            task = self.task(task_name)
            if task.running:
                raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
            if not (math.isfinite(rate) and 0 < rate <= self.spec.max_aggregate_rate):
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: SampClk.Rate\nRequested Value: {rate}\n"
                                 f"Maximum Value: {self.spec.max_aggregate_rate:g}")
            if sample_mode not in (CONTINUOUS, FINITE):
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: SampQuant.SampMode\nRequested Value: {sample_mode}")
            if samps_per_chan < 1 and sample_mode == FINITE:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: SampQuant.SampPerChan\nRequested: {samps_per_chan}")
            task.rate, task.sample_mode = float(rate), sample_mode
            task.samps_per_chan, task.timing_set = int(samps_per_chan), True

    def set_on_demand(self, task_name: str) -> None:
        """Samp.TimingType = On Demand: drop the sample clock."""
        with self._lock:
            task = self.task(task_name)
            if task.running:
                raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
            task.timing_set = False

    def max_rate(self, task_name: str) -> float:
        """Sample clock limit for the task: the aggregate rate over its channels."""
        with self._lock:
            n = max(1, len(self.task(task_name).channels))
        return self.spec.max_aggregate_rate / n

    def set_buffer_size(self, task_name: str, size: int) -> None:
        """Buf.Input.BufSize: the caller's size replaces DAQmx's rule at the next start."""
        with self._lock:
            task = self.task(task_name)
            if task.running:
                raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING,
                                 "Property: Buf.Input.BufSize")
            if size < 2:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: Buf.Input.BufSize\n"
                                 f"Requested Value: {size}\nMinimum Value: 2")
            task.buffer_request = int(size)

    def buffer_size(self, task_name: str) -> int:
        """The buffer (samples per channel) the task has, or will have when it starts."""
        with self._lock:
            task = self.task(task_name)
            return task.buffer_size if task.running else self._buffer_size(task)

    def start(self, task_name: str) -> None:
        with self._lock:
            self._start(self.task(task_name))

    def _start(self, task: SimTask) -> None:
        if task.running:
            return
        if not task.channels:
            raise DaqmxError(NO_CHANS_IN_TASK, f"Task Name: {task.name}")
        n_chan = len(task.channels)
        limit = self.spec.max_aggregate_rate / n_chan
        if task.timing_set and task.rate > limit:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                             f"Property: SampClk.Rate\nRequested Value: {task.rate:g}\n"
                             f"Maximum Value: {limit:g} ({self.spec.max_aggregate_rate:g} "
                             f"S/s aggregate over {n_chan} channels)")
        if any(t.running for t in self._tasks.values()):
            raise DaqmxError(RESOURCE_RESERVED, f"Device: {self.spec.name}\nTask Name: "
                             f"{task.name}\nAnother analog input task is running.")
        task.buffer_size = self._buffer_size(task)
        task.read_pos, task.overflowed, task.auto_started = 0, False, False
        task.gen_pos, task.hist_start, task.hist_off = 0, 0, 0
        task.hist = task.hist_buf = np.empty((n_chan, 0))
        task.t0 = self.clock.now()
        if task.start_gate is not None:
            task.t0 = task.start_gate(task.t0)
        task.timing = self.spec.timing
        task.running = True

    def _buffer_size(self, task: SimTask) -> int:
        if task.buffer_request is not None:
            return task.buffer_request
        if self.buffer_override is not None:
            return self.buffer_override
        if task.sample_mode == FINITE:
            return task.samps_per_chan
        return max(task.samps_per_chan, default_buffer_size(task.rate))

    def stop(self, task_name: str) -> None:
        with self._lock:
            task = self.task(task_name)
            task.running = task.auto_started = False

    def reset(self) -> None:
        """DAQmx Reset Device: abort every task (they stay, stopped) and reset the device."""
        with self._lock:
            for task in self._tasks.values():
                task.running = task.auto_started = False

    def task_names(self) -> list[str]:
        with self._lock:
            return list(self._tasks)

    # --- task state ------------------------------------------------------------------------

    def is_done(self, task_name: str) -> bool:
        with self._lock:
            return self.task(task_name).done(self.clock.now())

    def wait_until_done(self, task_name: str, timeout: float) -> None:
        """Wait on the clock until the task is done, up to ``timeout`` s (-1: no limit).

        A continuous task is never done: it waits ``timeout`` and fails with -200560, and
        with no limit it fails at once (the device would wait forever).
        """
        with self._lock:
            task = self.task(task_name)
            now = self.clock.now()
            if task.done(now):
                return
            if task.sample_mode == FINITE:
                target = task.delivered_at(task.samps_per_chan - 1)
            else:
                target = math.inf
            limit = math.inf if timeout < 0 else now + timeout
        if target <= limit:
            self.clock.sleep_until(target)
            return
        if math.isfinite(limit):
            self.clock.sleep_until(limit)
        with self._lock:
            if self._tasks.get(task_name) is not task or task.done(self.clock.now()):
                return
        forever = "" if math.isfinite(limit) else "\nA continuous task is never done."
        raise DaqmxError(WAIT_UNTIL_DONE_DOES_NOT_INDICATE_DONE,
                         f"Task Name: {task_name}\nTimeout: {timeout} s{forever}")

    # --- reading ---------------------------------------------------------------------------

    def available(self, task_name: str) -> int:
        """Unread samples per channel in the buffer now."""
        with self._lock:
            task = self.task(task_name)
            return max(0, task.acquired(self.clock.now()) - task.read_pos)

    def total_acquired(self, task_name: str) -> int:
        with self._lock:
            return self.task(task_name).acquired(self.clock.now())

    def read(self, task_name: str, n: int, timeout: float) -> tuple[FloatArray, int]:
        """Read ``n`` samples per channel (-1: all available); return (channels x n, n).

        A task that is not running is started by the read (Read.AutoStart, on by default)
        and stopped when the read is done with it: after each read on demand or continuous,
        after the last sample of a finite acquisition. On demand (no sample clock) the
        samples are taken now. Otherwise the read waits on the clock for samples not yet
        acquired, up to ``timeout`` (s, -1 = forever), starting where Read.RelativeTo and
        Read.Offset say.
        """
        with self._lock:
            task = self.task(task_name)
            if not task.running:
                if not task.auto_start:
                    raise DaqmxError(CANNOT_READ_TASK_NOT_RUNNING, f"Task Name: {task_name}",
                                     samps_read=0)
                self._start(task)
                task.auto_started = True
            if not task.timing_set:
                data, last = self._read_on_demand(task, n)
            else:
                last = None
        if last is not None:
            self.clock.sleep_until(last)
            return data, data.shape[1]
        return self._read_clocked(task, n, timeout)

    def _read_on_demand(self, task: SimTask, n: int) -> tuple[FloatArray, float]:
        """``n`` fresh samples (-1: one) at the aggregate rate from now; the last one's time."""
        n = 1 if n == READ_ALL_AVAILABLE else n
        dt = len(task.channels) / self.spec.max_aggregate_rate
        t_first = max(self.clock.now(), task.on_demand_next)
        data = self._generate(task, t_first, dt, n)
        task.on_demand_next = t_first + n * dt
        if task.auto_started:
            task.running = task.auto_started = False
        return data, t_first + max(n - 1, 0) * dt

    def _read_start(self, task: SimTask, acquired: int) -> int:
        if task.relative_to in (REFERENCE_TRIGGER, FIRST_PRETRIGGER_SAMPLE):
            raise DaqmxError(NO_REF_TRIG_CONFIGURED, "Property: Read.RelativeTo", samps_read=0)
        base = {FIRST_SAMPLE: 0, MOST_RECENT_SAMPLE: acquired}.get(task.relative_to,
                                                                   task.read_pos)
        start = base + task.offset
        if start < 0:
            raise DaqmxError(NEGATIVE_READ_SAMPLE_NUMBER,
                             f"Read.RelativeTo position: {base}\nRead.Offset: {task.offset}",
                             samps_read=0)
        return start

    def _read_clocked(self, task: SimTask, n: int, timeout: float) -> tuple[FloatArray, int]:
        with self._lock:
            if task.overwrite == DO_NOT_OVERWRITE_UNREAD:
                self._check_overflow(task)
            now = self.clock.now()
            acquired = task.acquired(now)
            start = self._read_start(task, acquired)
            if n == READ_ALL_AVAILABLE:
                whole = task.sample_mode == FINITE and not task.read_all_avail
                n = max(0, (task.samps_per_chan if whole else acquired) - start)
            if task.sample_mode == FINITE and start + n > task.samps_per_chan:
                raise DaqmxError(SAMPLES_WILL_NEVER_BE_AVAILABLE,
                                 f"Samples requested: {n} from sample {start}; the acquisition "
                                 f"ends at sample {task.samps_per_chan}", samps_read=0)
            if start < acquired - task.buffer_size:
                raise DaqmxError(SAMPLES_NO_LONGER_AVAILABLE,
                                 f"Samples overwritten before sample {acquired - task.buffer_size}"
                                 f"; read from sample {start}\nBuffer size: {task.buffer_size} "
                                 f"samples per channel\nTask Name: {task.name}", samps_read=0)
            deadline = task.delivered_at(start + n - 1)
            short = acquired < start + n
        if short:
            limit = math.inf if timeout < 0 else now + timeout
            self.clock.sleep_until(min(deadline, limit))
        with self._lock:
            if self._tasks.get(task.name) is not task or not task.running:
                raise DaqmxError(TRANSFER_ABORTED, f"Task Name: {task.name}", samps_read=0)
            # No overflow check here: a waiting read drains the buffer as samples arrive.
            got = max(0, min(n, task.acquired(self.clock.now()) - start))
            data = self._samples(task, start, got)
            task.read_pos = start + got
            if task.auto_started and (task.sample_mode != FINITE
                                      or task.read_pos >= task.samps_per_chan):
                task.running = task.auto_started = False
            if got < n:
                raise DaqmxError(SAMPLES_NOT_YET_AVAILABLE,
                                 f"Attempted to read samples: {n}\nAcquired samples: {got}\n"
                                 f"Timeout: {timeout} s", samps_read=got, data=data)
            return data, got

    def _check_overflow(self, task: SimTask) -> None:
        if not task.overflowed:
            unread = task.acquired(self.clock.now()) - task.read_pos
            task.overflowed = unread > task.buffer_size
        if task.overflowed:
            raise DaqmxError(SAMPLES_NO_LONGER_AVAILABLE,
                             f"Buffer size: {task.buffer_size} samples per channel\n"
                             f"Task Name: {task.name}", samps_read=0)

    def _samples(self, task: SimTask, start: int, n: int) -> FloatArray:
        """Samples ``start .. start + n`` of every channel, each computed once and kept while
        the buffer holds it (a read relative to the first or most recent sample re-reads)."""
        end = start + n
        if end > task.gen_pos:
            keep = max(task.buffer_size, n)
            first = max(task.gen_pos, end - keep)
            dt = 1.0 / task.true_rate
            block = self._generate(task, task.t0 + first * dt, dt, end - first)
            _keep_history(task, block, first, keep)
            task.gen_pos = end
        i = start - task.hist_start
        if i < 0:
            raise DaqmxError(SAMPLES_NO_LONGER_AVAILABLE, f"Sample {start} was overwritten.",
                             samps_read=0)
        return task.hist[:, i:i + n].copy()

    def _generate(self, task: SimTask, t_first: float, dt: float, n: int) -> FloatArray:
        """ADC codes as volts for ``n`` samples of every channel at ``t_first + k dt``."""
        out = np.empty((len(task.channels), n))
        if n == 0:
            return out
        clip, lsb = self.spec.clip_volts, self.spec.lsb
        for row, chan in zip(out, task.channels, strict=True):
            v = self.sources[chan.physical].volts(t_first, dt, n)
            np.clip(v, -clip, clip, out=v)
            np.round(v / lsb, out=row)
            row *= lsb
        return out


def add_named(channels: list[Any], new: list[Any]) -> None:
    """Append ``new`` channels to a task's; a name already there (any case): -200489."""
    taken = {c.name.lower() for c in channels}
    for chan in new:
        if chan.name.lower() in taken:
            raise DaqmxError(CHAN_ALREADY_IN_TASK, f"Channel Name: {chan.name}")
        taken.add(chan.name.lower())
    channels.extend(new)


def default_terminal(physical: str) -> int:
    """DAQmx's terminal configuration for -1 (Default) on an 8-channel USB-600x: differential
    for ai0..3, RSE for ai4..7 (NI-DAQmx Help, "Default Input/Output Terminal Configurations")."""
    return DIFF if int(physical[2:]) < 4 else RSE


def _keep_history(task: SimTask, block: FloatArray, first: int, keep: int) -> None:
    """Append ``block`` (samples ``first ..``) to ``task.hist`` and keep its last ``keep``
    samples: what ``concatenate`` then a slice give, written into storage with room for
    about ``keep`` more, so a read copies its own samples, not the whole buffer."""
    n = block.shape[1]
    if first > task.gen_pos:  # nothing kept joins this block
        task.hist, task.hist_start, task.hist_off = task.hist[:, :0], first, 0
    size = task.hist.shape[1]
    buf = task.hist_buf
    if task.hist_off + size + n > buf.shape[1]:
        retain = min(size, max(0, keep - n))
        fresh = np.empty((block.shape[0], max(2 * keep, retain + n)))
        fresh[:, :retain] = task.hist[:, size - retain:]
        task.hist_start += size - retain
        buf, task.hist_buf, task.hist_off, size = fresh, fresh, 0, retain
    end = task.hist_off + size
    buf[:, end:end + n] = block
    size += n
    drop = max(0, size - keep)
    task.hist_off += drop
    task.hist_start += drop
    task.hist = buf[:, task.hist_off:task.hist_off + size - drop]
