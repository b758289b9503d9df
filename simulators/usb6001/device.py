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
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from instrument.clock import Clock
from instrument.contact import FloatArray
from simulators.usb6001.signals import ConstantSignal, SignalSource

# DAQmx constants (nidaqmx.constants) used on the wire.
RSE, DIFF, NRSE, PSEUDO_DIFF, DEFAULT_TERMINAL = 10083, 10106, 10078, 12529, -1
VOLTS = 10348
FROM_CUSTOM_SCALE = 10065
CONTINUOUS, FINITE = 10123, 10178
GROUP_BY_CHANNEL, GROUP_BY_SCAN_NUMBER = 0, 1
MEAS_VOLTAGE = 10322
READ_ALL_AVAILABLE = -1

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
CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING = -200479
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
    CANNOT_READ_TASK_NOT_RUNNING: "The task is not running: start it before reading.",
    CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING: "Specified operation cannot be performed while the "
    "task is running.",
    RESOURCE_RESERVED: "The specified resource is reserved. The operation could not be "
    "completed as specified.",
    TRANSFER_ABORTED: "Transfer aborted: the task was stopped while a read was waiting.",
}


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

    @property
    def lsb(self) -> float:
        """One ADC code (V): the +-10 V span over 2^bits codes."""
        return 2.0 * self.range_volts / 2**self.resolution_bits


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


@dataclass
class SimTask:
    """A DAQmx task on the simulated device."""

    name: str
    channels: list[AIChannel] = field(default_factory=list)
    rate: float = 1000.0
    sample_mode: int = FINITE
    samps_per_chan: int = 1000
    timing_set: bool = False
    running: bool = False
    t0: float = 0.0
    read_pos: int = 0
    overflowed: bool = False
    buffer_size: int = 1000

    def acquired(self, now: float) -> int:
        """Samples per channel acquired by ``now`` (sample k exists at t0 + k / rate)."""
        if not self.running or now < self.t0:
            return 0
        n = math.floor((now - self.t0) * self.rate + 1e-6) + 1
        return min(n, self.samps_per_chan) if self.sample_mode == FINITE else n


_CHAN = re.compile(r"^\s*(?P<dev>[^/\s]+)/ai(?P<a>\d+)(?::(?P<b>\d+))?\s*$", re.IGNORECASE)


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
            terminal = DIFF if terminal == DEFAULT_TERMINAL else terminal
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
            for i, (full, short) in enumerate(physicals):
                name = names[i] if names else full
                task.channels.append(AIChannel(name, short, terminal, min_val, max_val))

    def _parse_channels(self, text: str, terminal: int) -> list[tuple[str, str]]:
        count = self.spec.rse_channels if terminal == RSE else self.spec.diff_channels
        out: list[tuple[str, str]] = []
        for part in text.split(","):
            m = _CHAN.match(part)
            if m is None:
                raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST, f"Physical Channel: {part.strip()}")
            if m["dev"] != self.spec.name:
                raise DaqmxError(INVALID_DEVICE_ID, f"Device Specified: {m['dev']}\n"
                                 f"Devices in System: {self.spec.name}")
            a = int(m["a"])
            b = int(m["b"]) if m["b"] is not None else a
            step = 1 if b >= a else -1
            for i in range(a, b + step, step):
                if i >= count:
                    raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST,
                                     f"Physical Channel: {m['dev']}/ai{i}\nThe "
                                     f"{self.spec.product_type} has ai0..ai{count - 1} "
                                     f"{'RSE' if terminal == RSE else 'differential'}.")
                out.append((f"{m['dev']}/ai{i}", f"ai{i}"))
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

    def max_rate(self, task_name: str) -> float:
        """Sample clock limit for the task: the aggregate rate over its channels."""
        with self._lock:
            n = max(1, len(self.task(task_name).channels))
        return self.spec.max_aggregate_rate / n

    def start(self, task_name: str) -> None:
        with self._lock:
            task = self.task(task_name)
            if task.running:
                return
            if not task.channels or not task.timing_set:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 "A task needs channels and a sample clock before it starts.")
            n_chan = len(task.channels)
            limit = self.spec.max_aggregate_rate / n_chan
            if task.rate > limit:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: SampClk.Rate\nRequested Value: {task.rate:g}\n"
                                 f"Maximum Value: {limit:g} ({self.spec.max_aggregate_rate:g} "
                                 f"S/s aggregate over {n_chan} channels)")
            if any(t.running for t in self._tasks.values()):
                raise DaqmxError(RESOURCE_RESERVED, f"Device: {self.spec.name}\nTask Name: "
                                 f"{task_name}\nAnother analog input task is running.")
            task.buffer_size = self._buffer_size(task)
            task.read_pos, task.overflowed = 0, False
            task.t0 = self.clock.now()
            task.running = True

    def _buffer_size(self, task: SimTask) -> int:
        if self.buffer_override is not None:
            return self.buffer_override
        if task.sample_mode == FINITE:
            return task.samps_per_chan
        return max(task.samps_per_chan, default_buffer_size(task.rate))

    def stop(self, task_name: str) -> None:
        with self._lock:
            self.task(task_name).running = False

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

        Waits on the clock for samples not yet acquired, up to ``timeout`` (s, -1 = forever).
        """
        with self._lock:
            task = self.task(task_name)
            if not task.running:
                raise DaqmxError(CANNOT_READ_TASK_NOT_RUNNING, f"Task Name: {task_name}")
            self._check_overflow(task)
            now = self.clock.now()
            if n == READ_ALL_AVAILABLE:
                if task.sample_mode == FINITE:
                    n = task.samps_per_chan - task.read_pos
                else:
                    n = task.acquired(now) - task.read_pos
            if task.sample_mode == FINITE and task.read_pos + n > task.samps_per_chan:
                raise DaqmxError(SAMPLES_WILL_NEVER_BE_AVAILABLE,
                                 f"Samples requested: {n}; remaining: "
                                 f"{task.samps_per_chan - task.read_pos}", samps_read=0)
            deadline = task.t0 + (task.read_pos + n - 1) / task.rate
            short = task.acquired(now) < task.read_pos + n
        if short:
            limit = math.inf if timeout < 0 else now + timeout
            self.clock.sleep_until(min(deadline, limit))
        with self._lock:
            if self._tasks.get(task_name) is not task or not task.running:
                raise DaqmxError(TRANSFER_ABORTED, f"Task Name: {task_name}", samps_read=0)
            # No overflow check here: a waiting read drains the buffer as samples arrive.
            got = min(n, task.acquired(self.clock.now()) - task.read_pos)
            data = self._samples(task, got)
            task.read_pos += got
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

    def _samples(self, task: SimTask, n: int) -> FloatArray:
        """ADC codes as volts for samples read_pos .. read_pos + n of every channel."""
        out = np.empty((len(task.channels), n))
        if n == 0:
            return out
        dt = 1.0 / task.rate
        t_first = task.t0 + task.read_pos * dt
        clip, lsb = self.spec.clip_volts, self.spec.lsb
        for row, chan in zip(out, task.channels, strict=True):
            v = self.sources[chan.physical].volts(t_first, dt, n)
            np.clip(v, -clip, clip, out=v)
            np.round(v / lsb, out=row)
            row *= lsb
        return out
