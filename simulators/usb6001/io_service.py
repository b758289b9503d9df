"""The NiDAQmx RPCs of the simulated USB-6001's AO, DIO, counter, triggers and waveform reads.

:class:`IoRpcs` is a base of :class:`~gelrig.simulators.usb6001.servicer.Usb6001Servicer`:
its handlers go to the device's :class:`~gelrig.simulators.usb6001.subsystems.Usb6001Io`.
What the USB-6001 lacks answers with the DAQmx code NI-DAQmx gives (docs/decisions/0290):
other AI/AO measurement types and counter measurements -200431, pulse generation -200430,
analog and reference triggers -200077, hardware-timed DIO and counters -200077 (On Demand).
"""

# ruff: noqa: N802  (RPC method names are fixed by the NiDAQmx gRPC service)
from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from nidaqmx._stubs import nidaqmx_pb2 as pb
from nitypes.waveform import AnalogWaveform, Timing

from gelrig.simulators.usb6001 import ao as ao_mod
from gelrig.simulators.usb6001 import counter as ctr
from gelrig.simulators.usb6001 import dio, tdms_log
from gelrig.simulators.usb6001 import triggers as trg
from gelrig.simulators.usb6001.device import (
    GROUP_BY_CHANNEL,
    GROUP_BY_SCAN_NUMBER,
    INVALID_ATTRIBUTE_VALUE,
    PHYSICAL_CHAN_DOES_NOT_EXIST,
    READ_BUFFER_TOO_SMALL,
    SAMPLES_NOT_YET_AVAILABLE,
    VOLTS,
    DaqmxError,
    InvalidRequest,
)
from gelrig.simulators.usb6001.ni_errors import (
    INVALID_PHYS_CHAN_TYPE,
    PHYS_CHAN_MEAS_TYPE,
    READ_NO_INPUT_CHANS,
    WRITE_NO_OUTPUT_CHANS,
    WRITE_NUM_CHANS_MISMATCH,
)
from gelrig.simulators.usb6001.subsystems import Usb6001Io, io_of

if TYPE_CHECKING:
    from gelrig.simulators.usb6001.device import SimulatedUsb6001

_AO = re.compile(r"^\s*/?(?P<dev>[^/\s]+)/ao(?P<a>\d+)(?::(?P<b>\d+))?\s*$", re.IGNORECASE)
_CTR = re.compile(r"^\s*/?(?P<dev>[^/\s]+)/ctr(?P<a>\d+)\s*$", re.IGNORECASE)
#: longest on-demand write the server takes in one call (values)
MAX_WRITE_VALUES = 8_000_000


def _raise(fault: DaqmxError) -> Any:
    raise fault


class IoRpcs:
    """RPC handlers for everything of the USB-6001 that is not analog input."""

    device: SimulatedUsb6001
    _run: Callable[..., Any]

    @property
    def io(self) -> Usb6001Io:
        return io_of(self.device)

    # --- channels ------------------------------------------------------------------------------

    def _ao_indices(self, text: str) -> list[tuple[str, int]]:
        out = []
        for part in text.split(","):
            m = _AO.match(part)
            if m is None:
                raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST, f"Physical Channel Name: "
                                 f"{part.strip()}\nPossible Values: {self._ao_list()}")
            self.device.check_device(m["dev"])
            a = int(m["a"])
            b = int(m["b"]) if m["b"] is not None else a
            step = 1 if b >= a else -1
            for i in range(a, b + step, step):
                if i >= ao_mod.AO_CHANNELS:
                    raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST,
                                     f"Physical Channel Name: {self.device.spec.name}/ao{i}\n"
                                     f"Possible Values: {self._ao_list()}")
                out.append((f"{self.device.spec.name}/ao{i}", i))
        return out

    def _ao_list(self) -> str:
        name = self.device.spec.name
        return ", ".join(f"{name}/ao{i}" for i in range(ao_mod.AO_CHANNELS))

    def CreateAOVoltageChan(self, request: Any, context: Any) -> Any:
        def create() -> Any:
            if request.custom_scale_name:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Custom scales are not simulated.")
            if request.units_raw != VOLTS:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_AO_Voltage_Units\n"
                                 f"Requested Value: {request.units_raw}\nPossible Values: "
                                 f"Volts ({VOLTS})")
            chans = self._ao_indices(request.physical_channel)
            names = [n.strip() for n in request.name_to_assign_to_channel.split(",")
                     ] if request.name_to_assign_to_channel else [f for f, _ in chans]
            if len(names) != len(chans):
                names = [f"{request.name_to_assign_to_channel}{k}" for k in range(len(chans))]
            task = self.io.claim(request.task.name, ao_mod.AOTask(request.task.name))
            taken = {c.name.lower() for c in task.channels} | {
                c.index for c in task.channels}
            for (_, i), n in zip(chans, names, strict=True):
                if n.lower() in taken or i in taken:
                    from gelrig.simulators.usb6001.device import CHAN_ALREADY_IN_TASK
                    raise DaqmxError(CHAN_ALREADY_IN_TASK, f"Channel Name: {n}")
            self.io.ao.add_channels(task, [i for _, i in chans], names, request.min_val,
                                    request.max_val)
            return pb.CreateAOVoltageChanResponse()

        return self._run(context, create)

    def _digital(self, request: Any, context: Any, output: bool, response: Any) -> Any:
        def create() -> Any:
            task = self.io.claim(request.task.name, dio.DigitalTask(request.task.name, output))
            dio.add_channels(task, request.lines, request.name_to_assign_to_lines,
                             request.line_grouping_raw, self.device.spec.name,
                             self.device.check_device)
            return response()

        return self._run(context, create)

    def CreateDIChan(self, request: Any, context: Any) -> Any:
        return self._digital(request, context, False, pb.CreateDIChanResponse)

    def CreateDOChan(self, request: Any, context: Any) -> Any:
        return self._digital(request, context, True, pb.CreateDOChanResponse)

    def _counter(self, text: str) -> str:
        m = _CTR.match(text)
        name = self.device.spec.name
        if m is None or int(m["a"]) != 0:
            raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST, f"Physical Channel Name: "
                             f"{text.strip()}\nPossible Values: {name}/ctr0")
        self.device.check_device(m["dev"])
        return f"{name}/ctr0"

    def CreateCICountEdgesChan(self, request: Any, context: Any) -> Any:
        def create() -> Any:
            full = self._counter(request.counter)
            chan = ctr.EdgeCountChannel(request.name_to_assign_to_channel or full,
                                        ctr.check_edge(request.edge_raw),
                                        ctr.check_initial(request.initial_count),
                                        ctr.check_direction(request.count_direction_raw))
            task = self.io.claim(request.task.name, ctr.CounterTask(request.task.name))
            if task.channel is not None:
                from gelrig.simulators.usb6001.device import RESOURCE_RESERVED
                raise DaqmxError(RESOURCE_RESERVED, f"Physical Channel: {full}\nThe "
                                 "USB-6001 has one counter, and the task already uses it.")
            task.channel = chan
            return pb.CreateCICountEdgesChanResponse()

        return self._run(context, create)

    # --- writing -------------------------------------------------------------------------------

    def _write_task(self, name: str) -> Any:
        task = self.io.get(name)
        if task is None:
            self.device.task(name)
        if not isinstance(task, ao_mod.AOTask | dio.DigitalTask) or (
                isinstance(task, dio.DigitalTask) and not task.output):
            raise DaqmxError(WRITE_NO_OUTPUT_CHANS, f"Task Name: {name}", samps_read=0)
        return task

    def _samples(self, flat: Any, n: int, n_chan: int, layout: int) -> np.ndarray:
        values = np.asarray(flat)
        if n < 0 or n * n_chan > MAX_WRITE_VALUES or values.size < n * n_chan:
            raise DaqmxError(WRITE_NUM_CHANS_MISMATCH, f"Samples per channel: {n}\nChannels: "
                             f"{n_chan}\nValues given: {values.size}", samps_read=0)
        values = values[:n * n_chan]
        if layout == GROUP_BY_SCAN_NUMBER:
            return values.reshape(n, n_chan).T
        if layout != GROUP_BY_CHANNEL:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Data layout: {layout}", samps_read=0)
        return values.reshape(n_chan, n)

    def _write_ao(self, name: str, values: np.ndarray, auto_start: bool, timeout: float) -> int:
        task = self._write_task(name)
        if not isinstance(task, ao_mod.AOTask):
            raise DaqmxError(WRITE_NO_OUTPUT_CHANS, f"Task Name: {name}\nNo analog output "
                             "channels in the task.", samps_read=0)
        if values.shape[0] != len(task.channels):
            raise DaqmxError(WRITE_NUM_CHANS_MISMATCH, f"Channels in task: "
                             f"{len(task.channels)}\nChannels in data: {values.shape[0]}",
                             samps_read=0)
        written = self.io.ao.write(task, values.astype(float), timeout)
        if task.timing_set and auto_start and not task.running:
            self.io.start(name)
            task.auto_started = True
        return written

    def WriteAnalogF64(self, request: Any, context: Any) -> Any:
        def write() -> Any:
            task = self._write_task(request.task.name)
            values = self._samples(request.write_array, request.num_samps_per_chan,
                                   len(task.channels), request.data_layout_raw)
            n = self._write_ao(request.task.name, values, request.auto_start, request.timeout)
            return pb.WriteAnalogF64Response(samps_per_chan_written=n)

        return self._run(context, write)

    def WriteAnalogScalarF64(self, request: Any, context: Any) -> Any:
        def write() -> Any:
            self._write_ao(request.task.name, np.array([[request.value]]), request.auto_start,
                           request.timeout)
            return pb.WriteAnalogScalarF64Response()

        return self._run(context, write)

    def WriteAnalogWaveforms(self, request: Any, context: Any) -> Any:
        def write() -> Any:
            from ni.protobuf.types.waveform_conversion import (
                float64_analog_waveform_from_protobuf,
            )
            try:
                waves = [float64_analog_waveform_from_protobuf(w) for w in request.waveforms]
            except (ValueError, TypeError, OverflowError) as exc:
                raise InvalidRequest(f"WriteAnalogWaveforms: waveforms: {exc}") from exc
            lengths = {w.sample_count for w in waves}
            if len(lengths) > 1:
                raise DaqmxError(WRITE_NUM_CHANS_MISMATCH, "Waveforms of different lengths",
                                 samps_read=0)
            values = np.array([w.scaled_data for w in waves]) if waves else np.empty((0, 0))
            n = self._write_ao(request.task.name, values, request.auto_start, request.timeout)
            return pb.WriteAnalogWaveformsResponse(samps_per_chan_written=n)

        return self._run(context, write)

    def _write_do(self, name: str, numbers: list[list[int]] | None,
                  levels: list[list[list[bool]]] | None) -> int:
        task = self._write_task(name)
        if not isinstance(task, dio.DigitalTask):
            raise DaqmxError(WRITE_NO_OUTPUT_CHANS, f"Task Name: {name}", samps_read=0)
        now = self.device.clock.now()
        if numbers is not None:
            for sample in numbers:
                dio.write_numbers(task, self.io.lines, sample, now)
            return len(numbers)
        assert levels is not None
        for lv in levels:
            dio.write_levels(task, self.io.lines, lv, now)
        return len(levels)

    def _scan(self, task: dio.DigitalTask, flat: Any, n: int, layout: int) -> list[list[Any]]:
        values = self._samples(flat, n, len(task.channels), layout)
        return [list(values[:, k]) for k in range(n)]

    def WriteDigitalU32(self, request: Any, context: Any) -> Any:
        def write() -> Any:
            task = self._write_task(request.task.name)
            samples = self._scan(task, list(request.write_array), request.num_samps_per_chan,
                                 request.data_layout_raw)
            n = self._write_do(request.task.name, samples, None)
            return pb.WriteDigitalU32Response(samps_per_chan_written=n)

        return self._run(context, write)

    def WriteDigitalScalarU32(self, request: Any, context: Any) -> Any:
        def write() -> Any:
            task = self._write_task(request.task.name)
            if len(task.channels) != 1:
                raise DaqmxError(WRITE_NUM_CHANS_MISMATCH, "A scalar write needs one channel.",
                                 samps_read=0)
            self._write_do(request.task.name, [[request.value]], None)
            return pb.WriteDigitalScalarU32Response()

        return self._run(context, write)

    def WriteDigitalLines(self, request: Any, context: Any) -> Any:
        def write() -> Any:
            task = self._write_task(request.task.name)
            if not isinstance(task, dio.DigitalTask):
                raise DaqmxError(WRITE_NO_OUTPUT_CHANS, "", samps_read=0)
            width = max(task.num_lines, 1)
            raw = np.frombuffer(request.write_array, dtype=np.uint8) != 0
            n, n_chan = request.num_samps_per_chan, len(task.channels)
            per = self._samples(raw.astype(np.uint8), n * width, n_chan,
                                request.data_layout_raw)  # channels x (n * width)
            levels = [[[bool(v) for v in per[c, k * width:(k + 1) * width]]
                       for c in range(n_chan)] for k in range(n)]
            done = self._write_do(request.task.name, None, levels)
            return pb.WriteDigitalLinesResponse(samps_per_chan_written=done)

        return self._run(context, write)

    def io_event_progress(self, name: str, kind: int) -> tuple[float, int] | None:
        """For an AO task and the transferred-from-buffer event (2): (start time or None
        while stopped, samples generated); None for any other task or event."""
        task = self.io.get(name)
        if kind != 2 or not isinstance(task, ao_mod.AOTask):
            return None
        if not task.running or not task.timing_set:
            return (math.nan, 0)
        return (task.t0, task.generated(self.device.clock.now()))

    # --- triggers and timing --------------------------------------------------------------------

    def io_timing(self, request: Any) -> bool:
        """CfgSampClkTiming of a task that is not AI: the AO's clock, or NI's refusal for the
        static DIO and the counter. False: an AI task (the device's own timing)."""
        task = self.io.get(request.task.name)
        if task is None:
            return False
        if isinstance(task, ao_mod.AOTask):
            self.io.ao.cfg_timing(task, request.rate, request.sample_mode_raw,
                                  request.samps_per_chan)
            return True
        if isinstance(task, dio.DigitalTask):
            raise dio.refuse_sample_clock(task)
        from gelrig.simulators.usb6001.io_properties import _counter_clock
        raise _counter_clock(task.name)

    def CfgDigEdgeStartTrig(self, request: Any, context: Any) -> Any:
        def cfg() -> Any:
            name = request.task.name
            io = self.io.get(name)
            if isinstance(io, dio.DigitalTask | ctr.CounterTask):
                what = "counter" if isinstance(io, ctr.CounterTask) else "digital lines"
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Property: DAQmx_StartTrig_Type\n"
                                 "Requested Value: Digital Edge\nPossible Values: None\n"
                                 f"The USB-6001's {what} take no trigger.")
            source = trg.check_source(request.trigger_source, self.device.spec.name,
                                      output=isinstance(io, ao_mod.AOTask))
            edge = trg.check_edge(request.trigger_edge_raw)
            trig = self.io.trigger(name)
            trig.kind, trig.source, trig.edge = trg.DIGITAL_EDGE, source, edge
            if io is None:
                self.io.arm_ai(name)
            return pb.CfgDigEdgeStartTrigResponse()

        return self._run(context, cfg)

    def DisableStartTrig(self, request: Any, context: Any) -> Any:
        def disable() -> Any:
            self.io.trigger(request.task.name).kind = trg.NO_TRIGGER
            if self.io.get(request.task.name) is None:
                self.io.arm_ai(request.task.name)
            return pb.DisableStartTrigResponse()

        return self._run(context, disable)

    # --- reading -------------------------------------------------------------------------------

    def _read_task(self, name: str, kind: type) -> Any:
        task = self.io.get(name)
        if task is None:
            self.device.task(name)
        if not isinstance(task, kind) or (isinstance(task, ao_mod.AOTask)):
            raise DaqmxError(READ_NO_INPUT_CHANS, f"Task Name: {name}", samps_read=0)
        return task

    @staticmethod
    def _count(n: int) -> int:
        if n > 1_000_000:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Samples per channel to read: {n}",
                             samps_read=0)
        return 1 if n < 0 else n

    def ReadDigitalLines(self, request: Any, context: Any) -> Any:
        def read() -> Any:
            task = self._read_task(request.task.name, dio.DigitalTask)
            n, width = self._count(request.num_samps_per_chan), max(task.num_lines, 1)
            if request.array_size_in_bytes < n * width * len(task.channels):
                raise DaqmxError(READ_BUFFER_TOO_SMALL, "", samps_read=0)
            sample = dio.read_lines(task, self.io.lines)
            rows = [[(lv + [False] * width)[:width] for _ in range(n)] for lv in sample]
            arr = np.array(rows, dtype=np.uint8)  # channels x n x width
            if request.fill_mode_raw == GROUP_BY_SCAN_NUMBER:
                arr = arr.transpose(1, 0, 2)
            return pb.ReadDigitalLinesResponse(read_array=arr.tobytes(), samps_per_chan_read=n,
                                               num_bytes_per_samp=width)

        return self._run(context, read)

    def ReadDigitalU32(self, request: Any, context: Any) -> Any:
        def read() -> Any:
            task = self._read_task(request.task.name, dio.DigitalTask)
            n = self._count(request.num_samps_per_chan)
            if request.array_size_in_samps < n * len(task.channels):
                raise DaqmxError(READ_BUFFER_TOO_SMALL, "", samps_read=0)
            sample = np.array(dio.read_numbers(task, self.io.lines), dtype=np.uint32)
            arr = np.repeat(sample[:, None], n, axis=1)
            flat = arr.T.ravel() if request.fill_mode_raw == GROUP_BY_SCAN_NUMBER else arr.ravel()
            return pb.ReadDigitalU32Response(read_array=flat.tolist(), samps_per_chan_read=n)

        return self._run(context, read)

    def ReadDigitalScalarU32(self, request: Any, context: Any) -> Any:
        def read() -> Any:
            task = self._read_task(request.task.name, dio.DigitalTask)
            if len(task.channels) != 1:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "A scalar read needs one channel.")
            return pb.ReadDigitalScalarU32Response(
                value=dio.read_numbers(task, self.io.lines)[0])

        return self._run(context, read)

    def _counts(self, name: str, n: int) -> list[int]:
        task = self._read_task(name, ctr.CounterTask)
        if task.channel is None:
            raise DaqmxError(READ_NO_INPUT_CHANS, f"Task Name: {name}", samps_read=0)
        auto = not task.running
        if auto:
            self.io.start(name)
        value = task.count(self.io.lines, self.device.clock.now())
        if auto:
            self.io.stop(name)
        return [value] * self._count(n)

    def ReadCounterF64Ex(self, request: Any, context: Any) -> Any:
        return self._run(context, lambda: pb.ReadCounterF64ExResponse(
            read_array=[float(v) for v in self._counts(request.task.name,
                                                       request.num_samps_per_chan)],
            samps_per_chan_read=self._count(request.num_samps_per_chan)))

    def ReadCounterF64(self, request: Any, context: Any) -> Any:
        return self._run(context, lambda: pb.ReadCounterF64Response(
            read_array=[float(v) for v in self._counts(request.task.name,
                                                       request.num_samps_per_chan)],
            samps_per_chan_read=self._count(request.num_samps_per_chan)))

    def ReadCounterU32Ex(self, request: Any, context: Any) -> Any:
        return self._run(context, lambda: pb.ReadCounterU32ExResponse(
            read_array=self._counts(request.task.name, request.num_samps_per_chan),
            samps_per_chan_read=self._count(request.num_samps_per_chan)))

    def ReadCounterU32(self, request: Any, context: Any) -> Any:
        return self._run(context, lambda: pb.ReadCounterU32Response(
            read_array=self._counts(request.task.name, request.num_samps_per_chan),
            samps_per_chan_read=self._count(request.num_samps_per_chan)))

    def ReadCounterScalarF64(self, request: Any, context: Any) -> Any:
        return self._run(context, lambda: pb.ReadCounterScalarF64Response(
            value=float(self._counts(request.task.name, 1)[0])))

    def ReadCounterScalarU32(self, request: Any, context: Any) -> Any:
        return self._run(context, lambda: pb.ReadCounterScalarU32Response(
            value=self._counts(request.task.name, 1)[0]))

    def read_ai(self, name: str, n: int, timeout: float) -> tuple[np.ndarray, int, int]:
        """An AI read: (channels x samples, samples, status); a read that times out answers
        the samples it got with status -200284, as DAQmx does."""
        self.io.logging.check_read(name)
        task = self.device.task(name)
        try:
            data, got = self.device.read(name, n, timeout)
            status = 0
        except DaqmxError as fault:
            if fault.code != SAMPLES_NOT_YET_AVAILABLE or fault.data is None:
                raise
            data, got, status = fault.data, fault.samps_read or 0, fault.code
        if task.timing_set:
            self.io.logging.append(task, data[:, :got], task.read_pos - got)
        return data, got, status

    def flush_log(self, name: str) -> None:
        """A task that logs only (Log mode): write what it acquired and nobody read."""
        setup = self.io.logging.setup(name)
        if setup is None or setup.mode != tdms_log.LOG or not self.device.has_task(name):
            return
        task = self.device.task(name)
        if not task.running or not task.timing_set:
            return
        n = self.device.available(name)
        if n:
            data, got = self.device.read(name, n, 0.0)
            self.io.logging.append(task, data[:, :got], task.read_pos - got)

    def ConfigureLogging(self, request: Any, context: Any) -> Any:
        def configure() -> Any:
            if self.io.get(request.task.name) is not None:
                task = self.io.get(request.task.name)
                from gelrig.simulators.usb6001.ni_errors import (
                    LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED,
                    LOGGING_NOT_SUPPORTED_ON_OUTPUT,
                )
                output = isinstance(task, ao_mod.AOTask) or (
                    isinstance(task, dio.DigitalTask) and task.output)
                raise DaqmxError(LOGGING_NOT_SUPPORTED_ON_OUTPUT if output
                                 else LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED,
                                 f"Task Name: {request.task.name}")
            self.io.logging.configure(self.device.task(request.task.name), request.file_path,
                                      request.logging_mode_raw, request.group_name,
                                      request.operation_raw)
            return pb.ConfigureLoggingResponse()

        return self._run(context, configure)

    def ReadAnalogWaveforms(self, request: Any, context: Any) -> Any:
        """One waveform per channel with its timing: t0 of its first sample and the sample
        interval (on demand: the aggregate conversion interval)."""
        from ni.protobuf.types.waveform_conversion import float64_analog_waveform_to_protobuf

        def read() -> Any:
            task = self.device.task(request.task.name)
            if not task.channels:
                raise DaqmxError(READ_NO_INPUT_CHANS, f"Task Name: {task.name}", samps_read=0)
            n = request.num_samps_per_chan
            if n * len(task.channels) > 8_000_000:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Samples per channel: {n}",
                                 samps_read=0)
            first = task.read_pos if task.running and task.timing_set else None
            data, got, status = self.read_ai(task.name, n, request.timeout)
            if task.timing_set:
                dt = 1.0 / task.true_rate
                start = task.t0 + (first if first is not None else task.read_pos - got) * dt
            else:
                dt = len(task.channels) / self.device.spec.max_aggregate_rate
                start = task.on_demand_next - got * dt
            waves = []
            for row, chan in zip(data, task.channels, strict=True):
                wave = AnalogWaveform.from_array_1d(row, dtype=np.float64)
                wave.timing = Timing.create_with_regular_interval(
                    _seconds(dt), _timestamp(start))
                wave.channel_name = chan.name
                wave.units = "Volts"
                waves.append(float64_analog_waveform_to_protobuf(wave))
            return pb.ReadAnalogWaveformsResponse(status=status, waveforms=waves,
                                                  samps_per_chan_read=got)

        return self._run(context, read)


def _seconds(dt: float) -> Any:
    import datetime as _dt
    return _dt.timedelta(seconds=dt)


def _timestamp(t: float) -> Any:
    """The clock's time as a timestamp: seconds since the Unix epoch (a virtual clock's 0 is
    1970-01-01, UTC)."""
    import datetime as _dt
    return _dt.datetime(1970, 1, 1, tzinfo=_dt.UTC) + _dt.timedelta(seconds=t)


def _refusal(rpc: str, make: Callable[[str], DaqmxError]) -> Callable[..., Any]:
    def handler(self: Any, request: Any, context: Any) -> Any:
        def refuse() -> Any:
            if hasattr(request, "task"):
                self.device.task(request.task.name)
            raise make(rpc)
        return self._run(context, refuse)

    handler.__name__ = handler.__qualname__ = rpc
    handler.__doc__ = f"DAQmx{rpc}: the USB-6001 lacks it; answers NI's code for that."
    return handler


def _meas_type(rpc: str) -> DaqmxError:
    return DaqmxError(PHYS_CHAN_MEAS_TYPE, f"DAQmx{rpc}: the USB-6001 measures voltage on ai0..7 "
                      "and counts edges on ctr0; it has no channel for this measurement.")


def _no_co(rpc: str) -> DaqmxError:
    return DaqmxError(INVALID_PHYS_CHAN_TYPE, f"DAQmx{rpc}: ctr0 of the USB-6001 is a counter "
                      "input only; the device has no counter output (pulse generation).")


def _timing_type(rpc: str) -> DaqmxError:
    kind = rpc.removeprefix("Cfg").removesuffix("Timing")
    return DaqmxError(INVALID_ATTRIBUTE_VALUE, f"DAQmx{rpc}\nProperty: DAQmx_SampTimingType\n"
                      f"Requested Value: {kind}\nPossible Values: Sample Clock (AI, AO), On "
                      "Demand")


def _pattern(rpc: str) -> DaqmxError:
    return DaqmxError(INVALID_ATTRIBUTE_VALUE, f"DAQmx{rpc}\nProperty: DAQmx_StartTrig_Type\n"
                      "Requested Value: Digital Pattern\nPossible Values: Digital Edge, None")


def _install_refusals() -> list[str]:
    names = [m.name for m in pb.DESCRIPTOR.services_by_name["NiDAQmx"].methods]
    made = []
    for rpc in names:
        make: Callable[[str], DaqmxError] | None = None
        if re.fullmatch(r"Create(TEDS)?(AI|AO|CI)\w+Chan\w*", rpc) and rpc not in (
                "CreateAIVoltageChan", "CreateAOVoltageChan", "CreateCICountEdgesChan"):
            make = _meas_type
        elif re.fullmatch(r"CreateCO\w+Chan\w*", rpc):
            make = _no_co
        elif re.fullmatch(r"CfgAnlg\w*StartTrig", rpc):
            make = trg.refuse_analog
        elif re.fullmatch(r"Cfg\w*RefTrig", rpc):
            make = trg.refuse_reference
        elif rpc == "CfgDigPatternStartTrig":
            make = _pattern
        elif rpc in ("CfgChangeDetectionTiming", "CfgHandshakingTiming", "CfgImplicitTiming",
                     "CfgBurstHandshakingTimingExportClock",
                     "CfgBurstHandshakingTimingImportClock", "CfgPipelinedSampClkTiming"):
            make = _timing_type
        if make is not None and not hasattr(IoRpcs, rpc):
            setattr(IoRpcs, rpc, _refusal(rpc, make))
            made.append(rpc)
    return made


#: RPCs answered with the code NI-DAQmx gives for what a USB-6001 lacks
REFUSED: tuple[str, ...] = tuple(_install_refusals())
