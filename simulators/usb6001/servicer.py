"""The simulated USB-6001 as the subset of the NI gRPC Device Server (NiDAQmx service) that a
voltage acquisition through the official ``nidaqmx`` client uses.

Error conventions follow the client's interpreter (nidaqmx/_grpc_interpreter.py): a failed RPC
ends with trailing metadata ``ni-error`` = the DAQmx code (plus ``ni-samps-per-chan-read`` for
reads), so the client raises DaqError / DaqReadError with that code; a read that times out
answers normally with ``status`` = -200284 and the samples it did get, as the device returns
them. RPCs outside the subset stay UNIMPLEMENTED (the client raises RpcError).

Named sessions follow the server's session initialisation behaviour (ADR 0061): a CreateTask
with a session name that exists attaches to it (AUTO, ATTACH_TO_EXISTING; the response says
``new_session_initialized = False``) or fails with ALREADY_EXISTS (INITIALIZE_NEW); attaching
to a name that does not exist fails with NOT_FOUND. The status codes are those of NI's
session-management examples; the real server's are UNVERIFIED.
"""

# ruff: noqa: N802  (RPC method names are fixed by the NiDAQmx gRPC service)
from __future__ import annotations

from collections.abc import Callable
from typing import Any, NoReturn, TypeAlias, TypeVar

import grpc
from nidaqmx._stubs import nidaqmx_pb2 as pb
from nidaqmx._stubs import nidaqmx_pb2_grpc as pb_grpc
from session_pb2 import (
    SESSION_INITIALIZATION_BEHAVIOR_ATTACH_TO_EXISTING,
    SESSION_INITIALIZATION_BEHAVIOR_INITIALIZE_NEW,
    Session,
)

from simulators.usb6001.device import (
    ATTR_NOT_SUPPORTED,
    ERROR_TEXT,
    GROUP_BY_CHANNEL,
    GROUP_BY_SCAN_NUMBER,
    INVALID_ATTRIBUTE_VALUE,
    INVALID_DEVICE_ID,
    MEAS_VOLTAGE,
    READ_BUFFER_TOO_SMALL,
    SAMPLES_NOT_YET_AVAILABLE,
    AIChannel,
    DaqmxError,
    SimTask,
    SimulatedUsb6001,
)

#: NI-DAQmx version the simulated server reports (major, minor, update).
DRIVER_VERSION = (23, 8, 0)
#: Onboard AI FIFO of the USB-6001 in samples (reported only; see docs/decisions/0011).
ONBOARD_FIFO = 2047

_TASK_START, _TASK_STOP, _TASK_ABORT = 0, 1, 6
CHANNEL_TYPE_AI = 10100

R = TypeVar("R")
Context: TypeAlias = grpc.ServicerContext


def _abort(context: Context, fault: DaqmxError) -> NoReturn:
    metadata: list[tuple[str, str]] = [("ni-error", str(fault.code))]
    if fault.samps_read is not None:
        metadata.append(("ni-samps-per-chan-read", str(fault.samps_read)))
    context.set_trailing_metadata(tuple(metadata))
    context.abort(grpc.StatusCode.UNKNOWN, str(fault))
    raise AssertionError("unreachable: context.abort raises")  # pragma: no cover


def _unsupported(attribute: int) -> DaqmxError:
    return DaqmxError(ATTR_NOT_SUPPORTED, f"Property ID: {attribute:#x}")


class Usb6001Servicer(pb_grpc.NiDAQmxServicer):
    """NiDAQmx gRPC service answering for one :class:`SimulatedUsb6001`."""

    def __init__(self, device: SimulatedUsb6001):
        self.device = device

    def _run(self, context: Context, fn: Callable[[], R]) -> R:
        try:
            return fn()
        except DaqmxError as fault:
            _abort(context, fault)

    def _task(self, session: Session) -> SimTask:
        return self.device.task(session.name)

    # --- system, device ----------------------------------------------------------------------

    def GetSystemInfoAttributeUInt32(self, request: Any, context: Context) -> Any:
        versions = dict(zip((0x1272, 0x1923, 0x2F22), DRIVER_VERSION, strict=True))

        def get() -> Any:
            if request.attribute_raw not in versions:
                raise _unsupported(request.attribute_raw)
            return pb.GetSystemInfoAttributeUInt32Response(value=versions[request.attribute_raw])

        return self._run(context, get)

    def GetSystemInfoAttributeString(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            if request.attribute_raw != 0x193B:  # Sys.DevNames
                raise _unsupported(request.attribute_raw)
            return pb.GetSystemInfoAttributeStringResponse(value=self.device.spec.name)

        return self._run(context, get)

    def _check_device(self, name: str) -> None:
        if name != self.device.spec.name:
            raise DaqmxError(INVALID_DEVICE_ID, f"Device Specified: {name}")

    def GetDeviceAttributeString(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            self._check_device(request.device_name)
            if request.attribute_raw != 0x631:  # Dev.ProductType
                raise _unsupported(request.attribute_raw)
            return pb.GetDeviceAttributeStringResponse(value=self.device.spec.product_type)

        return self._run(context, get)

    def GetDeviceAttributeUInt32(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            self._check_device(request.device_name)
            if request.attribute_raw != 0x632:  # Dev.SerialNum
                raise _unsupported(request.attribute_raw)
            return pb.GetDeviceAttributeUInt32Response(value=self.device.spec.serial)

        return self._run(context, get)

    def GetErrorString(self, request: Any, context: Context) -> Any:
        return pb.GetErrorStringResponse(error_string=ERROR_TEXT.get(request.error_code, ""))

    # --- task lifecycle ----------------------------------------------------------------------

    def CreateTask(self, request: Any, context: Context) -> Any:
        name, behavior = request.session_name, request.initialization_behavior
        if name and self.device.has_task(name):
            if behavior == SESSION_INITIALIZATION_BEHAVIOR_INITIALIZE_NEW:
                context.abort(grpc.StatusCode.ALREADY_EXISTS,
                              f"Cannot initialize '{name}': a session of that name exists.")
            return pb.CreateTaskResponse(task=Session(name=name), new_session_initialized=False)
        if behavior == SESSION_INITIALIZATION_BEHAVIOR_ATTACH_TO_EXISTING:
            context.abort(grpc.StatusCode.NOT_FOUND,
                          f"Cannot attach to '{name}': no session of that name exists.")

        def create() -> Any:
            created = self.device.create_task(name)
            return pb.CreateTaskResponse(task=Session(name=created), new_session_initialized=True)

        return self._run(context, create)

    def ClearTask(self, request: Any, context: Context) -> Any:
        self._run(context, lambda: self.device.clear_task(request.task.name))
        return pb.ClearTaskResponse()

    def StartTask(self, request: Any, context: Context) -> Any:
        self._run(context, lambda: self.device.start(request.task.name))
        return pb.StartTaskResponse()

    def StopTask(self, request: Any, context: Context) -> Any:
        self._run(context, lambda: self.device.stop(request.task.name))
        return pb.StopTaskResponse()

    def TaskControl(self, request: Any, context: Context) -> Any:
        def control() -> Any:
            action = request.action_raw
            if action == _TASK_START:
                self.device.start(request.task.name)
            elif action in (_TASK_STOP, _TASK_ABORT):
                self.device.stop(request.task.name)
            else:
                self.device.task(request.task.name)  # verify/commit/reserve: validity only
            return pb.TaskControlResponse()

        return self._run(context, control)

    def GetTaskAttributeString(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            values = {
                0x1276: task.name,
                0x1273: ", ".join(c.name for c in task.channels),
                0x230E: self.device.spec.name if task.channels else "",
            }
            if request.attribute_raw not in values:
                raise _unsupported(request.attribute_raw)
            return pb.GetTaskAttributeStringResponse(value=values[request.attribute_raw])

        return self._run(context, get)

    def GetTaskAttributeUInt32(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            values = {0x2181: len(task.channels), 0x29BA: 1 if task.channels else 0}
            if request.attribute_raw not in values:
                raise _unsupported(request.attribute_raw)
            return pb.GetTaskAttributeUInt32Response(value=values[request.attribute_raw])

        return self._run(context, get)

    # --- channels and timing -----------------------------------------------------------------

    def CreateAIVoltageChan(self, request: Any, context: Context) -> Any:
        def create() -> Any:
            if request.custom_scale_name:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Custom scales are not simulated.")
            self.device.add_voltage_channel(
                request.task.name, request.physical_channel, request.name_to_assign_to_channel,
                request.terminal_config_raw, request.min_val, request.max_val, request.units_raw,
            )
            return pb.CreateAIVoltageChanResponse()

        return self._run(context, create)

    @staticmethod
    def _chan_value(task: SimTask, names: str, get: Callable[[AIChannel], R]) -> R:
        """A channel property for one channel or a list of them (which must agree)."""
        wanted = [n.strip() for n in names.split(",") if n.strip()]
        chans = [c for c in task.channels if c.name in wanted] if wanted else task.channels
        if not chans or (wanted and len(chans) != len(wanted)):
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Channel Name: {names}")
        values = {get(c) for c in chans}
        if len(values) != 1:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Channels {names} differ in this property")
        return values.pop()

    def GetChanAttributeInt32(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            getters: dict[int, Callable[[AIChannel], int]] = {
                0x1097: lambda c: c.terminal,
                0x0695: lambda c: MEAS_VOLTAGE,
                0x187F: lambda c: CHANNEL_TYPE_AI,
            }
            if request.attribute_raw not in getters:
                raise _unsupported(request.attribute_raw)
            value = self._chan_value(self._task(request.task), request.channel,
                                     getters[request.attribute_raw])
            return pb.GetChanAttributeInt32Response(value_raw=value)

        return self._run(context, get)

    def GetChanAttributeDouble(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            spec = self.device.spec
            getters: dict[int, Callable[[AIChannel], float]] = {
                0x17DD: lambda c: c.max_val,
                0x17DE: lambda c: c.min_val,
                0x1815: lambda c: spec.range_volts,
                0x1816: lambda c: -spec.range_volts,
                0x1765: lambda c: float(spec.resolution_bits),
            }
            if request.attribute_raw not in getters:
                raise _unsupported(request.attribute_raw)
            value = self._chan_value(self._task(request.task), request.channel,
                                     getters[request.attribute_raw])
            return pb.GetChanAttributeDoubleResponse(value=value)

        return self._run(context, get)

    def CfgSampClkTiming(self, request: Any, context: Context) -> Any:
        def cfg() -> Any:
            self.device.cfg_timing(request.task.name, request.rate, request.sample_mode_raw,
                                   request.samps_per_chan)
            return pb.CfgSampClkTimingResponse()

        return self._run(context, cfg)

    def GetTimingAttributeDouble(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw == 0x1344:
                value = task.rate
            elif request.attribute_raw == 0x22C8:
                value = self.device.max_rate(task.name)
            else:
                raise _unsupported(request.attribute_raw)
            return pb.GetTimingAttributeDoubleResponse(value=value)

        return self._run(context, get)

    def GetTimingAttributeInt32(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw != 0x1300:
                raise _unsupported(request.attribute_raw)
            return pb.GetTimingAttributeInt32Response(value_raw=task.sample_mode)

        return self._run(context, get)

    def GetTimingAttributeUInt64(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw != 0x1310:
                raise _unsupported(request.attribute_raw)
            return pb.GetTimingAttributeUInt64Response(value=task.samps_per_chan)

        return self._run(context, get)

    def GetBufferAttributeUInt32(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw == 0x186C:
                value = task.buffer_size
            elif request.attribute_raw == 0x230A:
                value = ONBOARD_FIFO
            else:
                raise _unsupported(request.attribute_raw)
            return pb.GetBufferAttributeUInt32Response(value=value)

        return self._run(context, get)

    # --- reading -----------------------------------------------------------------------------

    def GetReadAttributeUInt32(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw == 0x217B:
                value = len(task.channels)
            elif request.attribute_raw == 0x1223:
                value = self.device.available(task.name)
            else:
                raise _unsupported(request.attribute_raw)
            return pb.GetReadAttributeUInt32Response(value=value)

        return self._run(context, get)

    def GetReadAttributeUInt64(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw == 0x192A:
                value = self.device.total_acquired(task.name)
            elif request.attribute_raw == 0x1221:
                value = task.read_pos
            else:
                raise _unsupported(request.attribute_raw)
            return pb.GetReadAttributeUInt64Response(value=value)

        return self._run(context, get)

    def GetReadAttributeString(self, request: Any, context: Context) -> Any:
        def get() -> Any:
            task = self._task(request.task)
            if request.attribute_raw != 0x1823:  # Read.ChannelsToRead
                raise _unsupported(request.attribute_raw)
            return pb.GetReadAttributeStringResponse(
                value=", ".join(c.name for c in task.channels))

        return self._run(context, get)

    def ReadAnalogF64(self, request: Any, context: Context) -> Any:
        def read() -> Any:
            task = self._task(request.task)
            n = request.num_samps_per_chan
            if request.fill_mode_raw not in (GROUP_BY_CHANNEL, GROUP_BY_SCAN_NUMBER):
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Fill mode: {request.fill_mode_raw}",
                                 samps_read=0)
            if n >= 0 and request.array_size_in_samps < n * len(task.channels):
                raise DaqmxError(READ_BUFFER_TOO_SMALL,
                                 f"Required size: {n * len(task.channels)}\n"
                                 f"Buffer size: {request.array_size_in_samps}", samps_read=0)
            try:
                data, got = self.device.read(task.name, n, request.timeout)
                status = 0
            except DaqmxError as fault:
                if fault.code != SAMPLES_NOT_YET_AVAILABLE or fault.data is None:
                    raise
                data, got, status = fault.data, fault.samps_read or 0, fault.code
            flat = data.T.ravel() if request.fill_mode_raw == GROUP_BY_SCAN_NUMBER else data.ravel()
            return pb.ReadAnalogF64Response(
                status=status, read_array=flat.tolist(), samps_per_chan_read=got)

        return self._run(context, read)
