"""The simulated USB-6001 as the subset of the NI gRPC Device Server (NiDAQmx service) that a
voltage acquisition through the official ``nidaqmx`` client uses.

Error conventions follow the client's interpreter (nidaqmx/_grpc_interpreter.py): a failed RPC
ends with trailing metadata ``ni-error`` = the DAQmx code (plus ``ni-samps-per-chan-read`` for
reads), so the client raises DaqError / DaqReadError with that code; a read that times out
answers normally with ``status`` = -200284 and the samples it did get, as the device returns
them. Every RPC of the service this simulator does not implement answers DAQmx -209876
naming the function, and every property it does not know answers -200197 naming the property
(docs/decisions/0120); none answers a bare UNIMPLEMENTED.

Properties are one table, :meth:`Usb6001Servicer._properties`: (group, id) -> getter / setter,
served by generic Get/Set/Reset<Group>Attribute<Type> handlers generated from the service
descriptor, like the catch-all.

Named sessions follow the server's session initialisation behaviour (ADR 0061): a CreateTask
with a session name that exists attaches to it (AUTO, ATTACH_TO_EXISTING; the response says
``new_session_initialized = False``) or fails with ALREADY_EXISTS (INITIALIZE_NEW); attaching
to a name that does not exist fails with NOT_FOUND. The status codes are those of NI's
session-management examples; the real server's are UNVERIFIED.

A malformed request never ends the server: one the server cannot decode gets gRPC's own
INTERNAL status; one whose values the device refuses gets its DAQmx error; a read asking for
more values than one reply message can carry (:data:`MAX_READ_VALUES`) is refused with
-200077 before anything is allocated; and should a handler fail otherwise, the failure is
logged (logger ``gelrig.simulators.usb6001``) and answered with status INTERNAL naming it.
"""

# ruff: noqa: N802  (RPC method names are fixed by the NiDAQmx gRPC service)
from __future__ import annotations

import functools
import logging
import re
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn, TypeAlias, TypeVar

import grpc
import nidaqmx
from nidaqmx._stubs import nidaqmx_pb2 as pb
from nidaqmx._stubs import nidaqmx_pb2_grpc as pb_grpc
from session_pb2 import (
    SESSION_INITIALIZATION_BEHAVIOR_ATTACH_TO_EXISTING,
    SESSION_INITIALIZATION_BEHAVIOR_INITIALIZE_NEW,
    Session,
)

from gelrig.simulators.usb6001 import io_properties
from gelrig.simulators.usb6001.device import (
    ATTR_NOT_SUPPORTED,
    ATTRIBUTE_NOT_SUPPORTED_IN_TASK_CONTEXT,
    CURRENT_READ_POSITION,
    DO_NOT_OVERWRITE_UNREAD,
    ERROR_TEXT,
    EVERY_N_SAMPS_TRANSFERRED_EVENT_NOT_SUPPORTED,
    FINITE,
    FIRST_PRETRIGGER_SAMPLE,
    FIRST_SAMPLE,
    FUNCTION_NOT_SUPPORTED_FOR_DEVICE,
    GROUP_BY_CHANNEL,
    GROUP_BY_SCAN_NUMBER,
    INVALID_ATTRIBUTE_VALUE,
    MEAS_VOLTAGE,
    MOST_RECENT_SAMPLE,
    OVERWRITE_UNREAD,
    READ_BUFFER_TOO_SMALL,
    REFERENCE_TRIGGER,
    VOLTS,
    AIChannel,
    DaqmxError,
    InvalidRequest,
    SimTask,
    SimulatedUsb6001,
)
from gelrig.simulators.usb6001.io_service import IoRpcs

log = logging.getLogger("gelrig.simulators.usb6001")

#: Largest gRPC message either side accepts (a 1 kHz read of 1000 s is 8 MB).
MAX_MESSAGE_BYTES = 64 * 1024 * 1024
#: Most values (samples x channels) one read answers: what fits one reply message.
MAX_READ_VALUES = (MAX_MESSAGE_BYTES - 1024 * 1024) // 8

#: NI-DAQmx version the simulated server reports (major, minor, update).
DRIVER_VERSION = (23, 8, 0)
#: Onboard AI FIFO of the USB-6001 in samples (reported only; see docs/decisions/0011).
ONBOARD_FIFO = 2047

_TASK_START, _TASK_STOP, _TASK_ABORT = 0, 1, 6
CHANNEL_TYPE_AI = 10100
SAMPLE_CLOCK_TIMING, ON_DEMAND_TIMING = 10388, 10390
RISING, FALLING = 10280, 10171
BUS_USB = 12586  # nidaqmx.constants.BusType.USB
PRODUCT_CATEGORY_USB_DAQ = 14646  # ProductCategory.USBDAQ (UNVERIFIED for the 6001)
RESOLUTION_BITS = 10109
USB_BULK = 12590
ACQUIRED_INTO_BUFFER, TRANSFERRED_FROM_BUFFER = 1, 2
ONBOARD_CLOCK = "OnboardClock"
#: Real time between checks of an every-N-samples event stream (s).
EVENT_POLL = 0.005

R = TypeVar("R")
Context: TypeAlias = grpc.ServicerContext


def _abort(context: Context, fault: DaqmxError) -> NoReturn:
    metadata: list[tuple[str, str]] = [("ni-error", str(fault.code))]
    if fault.samps_read is not None:
        metadata.append(("ni-samps-per-chan-read", str(fault.samps_read)))
    context.set_trailing_metadata(tuple(metadata))
    context.abort(grpc.StatusCode.UNKNOWN, str(fault))
    raise AssertionError("unreachable: context.abort raises")  # pragma: no cover


_ATTRIBUTE_RPC = re.compile(r"^(Get|Set|Reset)(\w+?)Attribute(\w*)$")
_PROPERTY_CALL = re.compile(
    r"_interpreter\.(?:get|set|reset)_(\w+?)_attribute\w*\(.*?(0x[0-9a-fA-F]+)\)")
_GROUPS = {"system_info": "SystemInfo", "device": "Device", "task": "Task", "chan": "Chan",
           "timing": "Timing", "buffer": "Buffer", "read": "Read", "trig": "Trig",
           "write": "Write", "exported_signal": "ExportedSignal", "cal_info": "CalInfo",
           "physical_chan": "PhysicalChan", "scale": "Scale", "watchdog": "Watchdog",
           "persisted_chan": "PersistedChan", "persisted_task": "PersistedTask",
           "persisted_scale": "PersistedScale"}


@functools.cache
def _property_names() -> dict[tuple[str, int], str]:
    """(group, id) -> the nidaqmx property ("Timing.samp_clk_src"), read from its source."""
    names: dict[tuple[str, int], str] = {}
    root = Path(nidaqmx.__file__).parent
    for path in sorted(root.rglob("*.py")):
        cls = prop = ""
        for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
            if line.startswith("class "):
                cls = line[6:].split("(")[0].split(":")[0].strip()
            elif line.lstrip().startswith("def "):
                prop = line.strip()[4:].split("(")[0]
            elif (m := _PROPERTY_CALL.search(line)) and m[1] in _GROUPS:
                names.setdefault((_GROUPS[m[1]], int(m[2], 16)), f"{cls.lstrip('_')}.{prop}")
    return names


def _property_label(group: str, attribute: int) -> str:
    name = _property_names().get((group, attribute))
    return f"{attribute:#x}" + (f" (nidaqmx {name})" if name else "")


def _unsupported(rpc: str, group: str, attribute: int) -> DaqmxError:
    label = _property_label(group, attribute)
    return DaqmxError(ATTR_NOT_SUPPORTED, f"DAQmx{rpc}, property {label}: the simulated "
                      f"USB-6001 does not support DAQmx{rpc} of this property")


def _no_function(rpc: str) -> DaqmxError:
    return DaqmxError(FUNCTION_NOT_SUPPORTED_FOR_DEVICE,
                      f"DAQmx{rpc}: the simulated USB-6001 does not support DAQmx{rpc}")


def _choice(prop: str, value: int, allowed: dict[str, int]) -> int:
    """``value`` if it is one of ``allowed`` (DAQmx name -> value), else DAQmx -200077."""
    if value not in allowed.values():
        listed = ", ".join(f"{v} ({k})" for k, v in allowed.items())
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                         f"Property: {prop}\nRequested Value: {value}\nPossible Values: {listed}")
    return value


def _constant(value: Any) -> Callable[[Any], Any]:
    return lambda request: value


@dataclass(frozen=True)
class Prop:
    """One DAQmx property: its name, value type (the RPC suffix), getter and setter.

    ``get`` and ``set`` take the request (task, channel or device in it); ``reset`` is the
    value a Reset<Group>Attribute sets (None: the setter's own default).
    """

    name: str
    kind: str
    get: Callable[[Any], Any]
    set: Callable[[Any, Any], None] | None = None
    reset: Any = None


class Usb6001Servicer(IoRpcs, pb_grpc.NiDAQmxServicer):
    """NiDAQmx gRPC service answering for one :class:`SimulatedUsb6001`."""

    def __init__(self, device: SimulatedUsb6001):
        self.device = device
        self.properties = self._properties()
        self._event_lock = threading.Lock()
        self._events: dict[str, int] = {}  # task -> registration number of its N-samples event
        self._registrations = 0

    def _run(self, context: Context, fn: Callable[[], R]) -> R:
        try:
            return fn()
        except DaqmxError as fault:
            _abort(context, fault)
        except InvalidRequest as exc:
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
            raise AssertionError("unreachable: context.abort raises") from exc
        except Exception as exc:  # a request the device code could not take: say so
            log.exception("simulated USB-6001: a request failed")
            context.abort(grpc.StatusCode.INTERNAL, f"the simulated USB-6001 could not "
                          f"handle the request: {type(exc).__name__}: {exc}")
            raise AssertionError("unreachable: context.abort raises") from exc

    def _task(self, session: Session) -> SimTask:
        return self.device.task(session.name)

    # --- properties --------------------------------------------------------------------------

    def _properties(self) -> dict[tuple[str, int], Prop]:
        dev, spec = self.device, self.device.spec
        name = spec.name
        versions = dict(zip((0x1272, 0x1923, 0x2F22), DRIVER_VERSION, strict=True))

        def task(r: Any) -> SimTask:
            return self._task(r.task)

        def chan(fn: Callable[[AIChannel], Any]) -> Callable[[Any], Any]:
            return lambda r: self._chan_value(task(r), r.channel, fn)

        def set_chan(fn: Callable[[AIChannel, Any], None]) -> Callable[[Any, Any], None]:
            def setter(r: Any, v: Any) -> None:
                for c in self._channels(task(r), r.channel):
                    fn(c, v)
            return setter

        def no_lowpass(r: Any, v: Any = None) -> NoReturn:
            raise DaqmxError(ATTRIBUTE_NOT_SUPPORTED_IN_TASK_CONTEXT,
                             f"Property: AI.Lowpass.Enable\nChannel Name: {r.channel}\n"
                             f"The {spec.product_type} has no lowpass filter.")

        def retime(r: Any, rate: float | None = None, mode: int | None = None,
                   samps: int | None = None) -> None:
            t = task(r)
            dev.cfg_timing(t.name, t.rate if rate is None else rate,
                           t.sample_mode if mode is None else mode,
                           t.samps_per_chan if samps is None else samps)

        def timing_type(r: Any, v: int) -> None:
            _choice("SampTimingType", v, {"SampleClock": SAMPLE_CLOCK_TIMING,
                                          "OnDemand": ON_DEMAND_TIMING})
            if v == ON_DEMAND_TIMING:
                dev.set_on_demand(task(r).name)
            else:
                retime(r)

        def clock_source(r: Any, v: str) -> None:
            if v.strip().lower() not in ("", ONBOARD_CLOCK.lower()):
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                 f"Property: SampClk.Src\nRequested Value: {v}\nThe simulated "
                                 f"{spec.product_type} clocks its input from {ONBOARD_CLOCK} only.")

        def rising_only(r: Any, v: int) -> None:
            _choice("SampClk.ActiveEdge", v, {"Rising": RISING})

        def set_field(field: str, check: Callable[[Any], Any] = lambda v: v
                      ) -> Callable[[Any, Any], None]:
            return lambda r, v: setattr(task(r), field, check(v))

        ai = ", ".join(f"{name}/ai{i}" for i in range(spec.rse_channels))
        lines0 = [f"{name}/port0/line{i}" for i in range(8)]
        lines = lines0 + [f"{name}/port1/line{i}" for i in range(4)] + [f"{name}/port2/line0"]
        terminals = [f"/{name}/PFI0", f"/{name}/PFI1", f"/{name}/ai/SampleClock",
                     f"/{name}/ai/StartTrigger", f"/{name}/ao/SampleClock",
                     f"/{name}/ao/StartTrigger", f"/{name}/Ctr0Source", f"/{name}/Ctr0Gate",
                     f"/{name}/Ctr0InternalOutput", f"/{name}/100kHzTimebase",
                     f"/{name}/20MHzTimebase"]

        table: dict[tuple[str, int], Prop] = {
            # system
            **{("SystemInfo", k): Prop(f"Sys.Version{i}", "UInt32", _constant(v))
               for i, (k, v) in enumerate(versions.items())},
            ("SystemInfo", 0x193B): Prop("Sys.DevNames", "String", lambda r: name),
            ("SystemInfo", 0x1267): Prop("Sys.Tasks", "String", lambda r: ""),
            ("SystemInfo", 0x1265): Prop("Sys.GlobalChans", "String", lambda r: ""),
            ("SystemInfo", 0x1266): Prop("Sys.Scales", "String", lambda r: ""),
            # device
            ("Device", 0x631): Prop("Dev.ProductType", "String", lambda r: spec.product_type),
            ("Device", 0x632): Prop("Dev.SerialNum", "UInt32", lambda r: spec.serial),
            ("Device", 0x22CA): Prop("Dev.IsSimulated", "Bool", lambda r: True),
            ("Device", 0x2326): Prop("Dev.BusType", "Int32", lambda r: BUS_USB),
            ("Device", 0x29A9): Prop("Dev.ProductCategory", "Int32",
                                     lambda r: PRODUCT_CATEGORY_USB_DAQ),
            ("Device", 0x2990): Prop("Dev.AI.VoltageRngs", "DoubleArray",
                                     lambda r: [-spec.range_volts, spec.range_volts]),
            ("Device", 0x298C): Prop("Dev.AI.MaxSingleChanRate", "Double",
                                     lambda r: spec.max_aggregate_rate),
            ("Device", 0x298D): Prop("Dev.AI.MaxMultiChanRate", "Double",
                                     lambda r: spec.max_aggregate_rate),
            ("Device", 0x2FD2): Prop("Dev.AI.MeasTypes", "Int32Array", lambda r: [MEAS_VOLTAGE]),
            ("Device", 0x298F): Prop("Dev.AI.SimultaneousSamplingSupported", "Bool",
                                     lambda r: False),
            ("Device", 0x231E): Prop("Dev.AI.PhysicalChans", "String", lambda r: ai),
            ("Device", 0x231F): Prop("Dev.AO.PhysicalChans", "String",
                                     lambda r: f"{name}/ao0, {name}/ao1"),
            ("Device", 0x2324): Prop("Dev.CI.PhysicalChans", "String", lambda r: f"{name}/ctr0"),
            ("Device", 0x2325): Prop("Dev.CO.PhysicalChans", "String", lambda r: ""),
            ("Device", 0x2320): Prop("Dev.DI.Lines", "String", lambda r: ", ".join(lines)),
            ("Device", 0x2322): Prop("Dev.DO.Lines", "String", lambda r: ", ".join(lines)),
            ("Device", 0x2321): Prop("Dev.DI.Ports", "String",
                                     lambda r: f"{name}/port0, {name}/port1, {name}/port2"),
            ("Device", 0x2323): Prop("Dev.DO.Ports", "String",
                                     lambda r: f"{name}/port0, {name}/port1, {name}/port2"),
            ("Device", 0x2A40): Prop("Dev.Terminals", "String", lambda r: ", ".join(terminals)),
            # task
            ("Task", 0x1276): Prop("Task.Name", "String", lambda r: task(r).name),
            ("Task", 0x1273): Prop("Task.Channels", "String",
                                   lambda r: ", ".join(c.name for c in task(r).channels)),
            ("Task", 0x230E): Prop("Task.Devices", "String",
                                   lambda r: name if task(r).channels else ""),
            ("Task", 0x2181): Prop("Task.NumChans", "UInt32", lambda r: len(task(r).channels)),
            ("Task", 0x29BA): Prop("Task.NumDevices", "UInt32",
                                   lambda r: 1 if task(r).channels else 0),
            ("Task", 0x1274): Prop("Task.Complete", "Bool",
                                   lambda r: dev.is_done(task(r).name)),
            # channels
            ("Chan", 0x1097): Prop("AI.TermCfg", "Int32", chan(lambda c: c.terminal)),
            ("Chan", 0x0695): Prop("AI.MeasType", "Int32", chan(lambda c: MEAS_VOLTAGE)),
            ("Chan", 0x187F): Prop("ChanType", "Int32", chan(lambda c: CHANNEL_TYPE_AI)),
            ("Chan", 0x1094): Prop("AI.Voltage.Units", "Int32", chan(lambda c: VOLTS)),
            ("Chan", 0x1764): Prop("AI.ResolutionUnits", "Int32", chan(lambda c: RESOLUTION_BITS)),
            ("Chan", 0x1821): Prop("AI.DataXferMech", "Int32", chan(lambda c: USB_BULK)),
            ("Chan", 0x17DD): Prop("AI.Max", "Double", chan(lambda c: c.max_val)),
            ("Chan", 0x17DE): Prop("AI.Min", "Double", chan(lambda c: c.min_val)),
            ("Chan", 0x1815): Prop("AI.Rng.High", "Double", chan(lambda c: spec.range_volts)),
            ("Chan", 0x1816): Prop("AI.Rng.Low", "Double", chan(lambda c: -spec.range_volts)),
            ("Chan", 0x1765): Prop("AI.Resolution", "Double",
                                   chan(lambda c: float(spec.resolution_bits))),
            ("Chan", 0x18F5): Prop("PhysicalChanName", "String",
                                   chan(lambda c: f"{name}/{c.physical}")),
            ("Chan", 0x1926): Prop("ChanDescr", "String", chan(lambda c: c.description),
                                   set_chan(lambda c, v: setattr(c, "description", v)), ""),
            ("Chan", 0x2304): Prop("ChanIsGlobal", "Bool", chan(lambda c: False)),
            ("Chan", 0x1802): Prop("AI.Lowpass.Enable", "Bool", no_lowpass, no_lowpass),
            # timing
            ("Timing", 0x1344): Prop("SampClk.Rate", "Double", lambda r: task(r).rate,
                                     lambda r, v: retime(r, rate=v), 1000.0),
            ("Timing", 0x22C8): Prop("SampClk.MaxRate", "Double",
                                     lambda r: dev.max_rate(task(r).name)),
            ("Timing", 0x1300): Prop("SampQuant.SampMode", "Int32",
                                     lambda r: task(r).sample_mode,
                                     lambda r, v: retime(r, mode=v), FINITE),
            ("Timing", 0x1310): Prop("SampQuant.SampPerChan", "UInt64",
                                     lambda r: task(r).samps_per_chan,
                                     lambda r, v: retime(r, samps=v), 1000),
            ("Timing", 0x1347): Prop("SampTimingType", "Int32",
                                     lambda r: SAMPLE_CLOCK_TIMING if task(r).timing_set
                                     else ON_DEMAND_TIMING, timing_type, ON_DEMAND_TIMING),
            ("Timing", 0x1852): Prop("SampClk.Src", "String", lambda r: ONBOARD_CLOCK,
                                     clock_source, ""),
            ("Timing", 0x1301): Prop("SampClk.ActiveEdge", "Int32", lambda r: RISING,
                                     rising_only, RISING),
            # buffer
            ("Buffer", 0x186C): Prop("Buf.Input.BufSize", "UInt32",
                                     lambda r: dev.buffer_size(task(r).name),
                                     lambda r, v: dev.set_buffer_size(task(r).name, v)),
            ("Buffer", 0x230A): Prop("Buf.Input.OnbrdBufSize", "UInt32", lambda r: ONBOARD_FIFO),
            # read
            ("Read", 0x217B): Prop("Read.NumChans", "UInt32", lambda r: len(task(r).channels)),
            ("Read", 0x1223): Prop("Read.AvailSampPerChan", "UInt32",
                                   lambda r: dev.available(task(r).name)),
            ("Read", 0x192A): Prop("Read.TotalSampPerChanAcquired", "UInt64",
                                   lambda r: dev.total_acquired(task(r).name)),
            ("Read", 0x1221): Prop("Read.CurrReadPos", "UInt64", lambda r: task(r).read_pos),
            ("Read", 0x1823): Prop("Read.ChannelsToRead", "String",
                                   lambda r: ", ".join(c.name for c in task(r).channels)),
            ("Read", 0x190A): Prop("Read.RelativeTo", "Int32", lambda r: task(r).relative_to,
                                   set_field("relative_to", lambda v: _choice(
                                       "Read.RelativeTo", v,
                                       {"FirstSample": FIRST_SAMPLE,
                                        "CurrReadPos": CURRENT_READ_POSITION,
                                        "RefTrig": REFERENCE_TRIGGER,
                                        "FirstPretrigSamp": FIRST_PRETRIGGER_SAMPLE,
                                        "MostRecentSamp": MOST_RECENT_SAMPLE})),
                                   CURRENT_READ_POSITION),
            ("Read", 0x190B): Prop("Read.Offset", "Int32", lambda r: task(r).offset,
                                   set_field("offset", int), 0),
            ("Read", 0x1211): Prop("Read.OverWrite", "Int32", lambda r: task(r).overwrite,
                                   set_field("overwrite", lambda v: _choice(
                                       "Read.OverWrite", v,
                                       {"OverwriteUnreadSamps": OVERWRITE_UNREAD,
                                        "DoNotOverwriteUnreadSamps": DO_NOT_OVERWRITE_UNREAD})),
                                   DO_NOT_OVERWRITE_UNREAD),
            ("Read", 0x1215): Prop("Read.ReadAllAvailSamp", "Bool",
                                   lambda r: task(r).read_all_avail,
                                   set_field("read_all_avail", bool), False),
            ("Read", 0x1826): Prop("Read.AutoStart", "Bool", lambda r: task(r).auto_start,
                                   set_field("auto_start", bool), True),
        }
        io_properties.extend(self, table)  # AO, DIO, counter, triggers (docs/decisions/0290)
        return table

    def _attribute(self, rpc: str, request: Any, context: Context) -> Any:
        """Get/Set/Reset<Group>Attribute<Type>: served from :attr:`properties`."""
        m = _ATTRIBUTE_RPC.match(rpc)
        assert m is not None
        verb, group, kind = m[1], m[2], m[3]
        response = getattr(pb, f"{rpc}Response")

        def serve() -> Any:
            if hasattr(request, "device_name"):
                self.device.check_device(request.device_name)
            prop = self.properties.get((group, request.attribute_raw))
            if prop is None or (verb != "Reset" and prop.kind != kind):
                raise _unsupported(rpc, group, request.attribute_raw)
            if verb == "Get":
                value = prop.get(request)
                out = response()
                field = "value_raw" if "value_raw" in out.DESCRIPTOR.fields_by_name else "value"
                if kind.endswith("Array"):
                    getattr(out, field).extend(value)
                else:
                    setattr(out, field, value)
                return out
            if prop.set is None:
                raise DaqmxError(ATTR_NOT_SUPPORTED, f"DAQmx{rpc}, property {prop.name} "
                                 f"({request.attribute_raw:#x}) is read-only.")
            if verb == "Set":
                has_raw = "value_raw" in request.DESCRIPTOR.fields_by_name
                raw = has_raw and request.WhichOneof("value_enum") == "value_raw"
                prop.set(request, request.value_raw if raw else request.value)
            elif prop.reset is not None:
                prop.set(request, prop.reset)
            else:
                raise DaqmxError(ATTR_NOT_SUPPORTED, f"DAQmx{rpc}, property {prop.name}: the "
                                 "simulated USB-6001 does not support resetting it.")
            return response()

        return self._run(context, serve)

    @staticmethod
    def _channels(task: SimTask, names: str) -> list[AIChannel]:
        """The task's channels named in ``names`` (all if empty); names are case-insensitive."""
        chans = io_properties.select(task.channels, names)  # "Dev1/ai0:7" too
        if not chans:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Channel Name: {names}")
        return chans

    @classmethod
    def _chan_value(cls, task: SimTask, names: str, get: Callable[[AIChannel], R]) -> R:
        """A channel property for one channel or a list of them (which must agree)."""
        values = {get(c) for c in cls._channels(task, names)}
        if len(values) != 1:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Channels {names} differ in this property")
        return values.pop()

    # --- system, device ----------------------------------------------------------------------

    def GetErrorString(self, request: Any, context: Context) -> Any:
        return pb.GetErrorStringResponse(error_string=ERROR_TEXT.get(request.error_code, ""))

    def ResetDevice(self, request: Any, context: Context) -> Any:
        def reset() -> Any:
            self.device.check_device(request.device_name)
            self.device.reset()
            self.io.reset()
            return pb.ResetDeviceResponse()

        return self._run(context, reset)

    def SelfTestDevice(self, request: Any, context: Context) -> Any:
        def test() -> Any:
            self.device.check_device(request.device_name)
            return pb.SelfTestDeviceResponse()

        return self._run(context, test)

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
        self.io.clear(request.task.name)
        return pb.ClearTaskResponse()

    def StartTask(self, request: Any, context: Context) -> Any:
        self._run(context, lambda: self._start(request.task.name))
        return pb.StartTaskResponse()

    def StopTask(self, request: Any, context: Context) -> Any:
        self._run(context, lambda: self._stop(request.task.name))
        return pb.StopTaskResponse()

    def _start(self, name: str) -> None:
        """Start an AI task on the device, any other on its io side."""
        if self.io.get(name) is not None:
            self.io.start(name)
        else:
            self.device.start(name)
            self.io.ai_started(self.device.task(name).t0)  # the AO may start with it

    def _stop(self, name: str) -> None:
        if self.io.get(name) is not None:
            self.io.stop(name)
        self.flush_log(name)
        self.device.stop(name)

    def TaskControl(self, request: Any, context: Context) -> Any:
        def control() -> Any:
            action = request.action_raw
            if action == _TASK_START:
                self._start(request.task.name)
            elif action in (_TASK_STOP, _TASK_ABORT):
                self._stop(request.task.name)
            else:
                self.device.task(request.task.name)  # verify/commit/reserve: validity only
            return pb.TaskControlResponse()

        return self._run(context, control)

    def IsTaskDone(self, request: Any, context: Context) -> Any:
        name = request.task.name
        return self._run(context, lambda: pb.IsTaskDoneResponse(
            is_task_done=self.io.is_done(name) if self.io.get(name) is not None
            else self.device.is_done(name)))

    def WaitUntilTaskDone(self, request: Any, context: Context) -> Any:
        def wait() -> Any:
            if self.io.get(request.task.name) is not None:
                self.io.wait_until_done(request.task.name, request.time_to_wait)
                return pb.WaitUntilTaskDoneResponse()
            self.device.wait_until_done(request.task.name, request.time_to_wait)
            self.flush_log(request.task.name)
            return pb.WaitUntilTaskDoneResponse()

        return self._run(context, wait)

    # --- channels and timing -----------------------------------------------------------------

    def CreateAIVoltageChan(self, request: Any, context: Context) -> Any:
        def create() -> Any:
            if request.custom_scale_name:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Custom scales are not simulated.")
            self.io.check_ai(request.task.name)
            self.device.add_voltage_channel(
                request.task.name, request.physical_channel, request.name_to_assign_to_channel,
                request.terminal_config_raw, request.min_val, request.max_val, request.units_raw,
            )
            return pb.CreateAIVoltageChanResponse()

        return self._run(context, create)

    def CfgSampClkTiming(self, request: Any, context: Context) -> Any:
        def cfg() -> Any:
            self.properties[("Timing", 0x1852)].set(request, request.source)  # type: ignore[misc]
            if self.io_timing(request):
                return pb.CfgSampClkTimingResponse()
            if request.active_edge_raw not in (RISING, 0):
                _choice("SampClk.ActiveEdge", request.active_edge_raw, {"Rising": RISING})
            self.device.cfg_timing(request.task.name, request.rate, request.sample_mode_raw,
                                   request.samps_per_chan)
            return pb.CfgSampClkTimingResponse()

        return self._run(context, cfg)

    # --- reading -----------------------------------------------------------------------------

    def ReadAnalogF64(self, request: Any, context: Context) -> Any:
        def read() -> Any:
            task = self._task(request.task)
            n = request.num_samps_per_chan
            if n * max(1, len(task.channels)) > MAX_READ_VALUES:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Samples per channel to read: {n}"
                                 f"\nThe simulated server answers at most {MAX_READ_VALUES} "
                                 "values per read (one gRPC message)", samps_read=0)
            if request.fill_mode_raw not in (GROUP_BY_CHANNEL, GROUP_BY_SCAN_NUMBER):
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Fill mode: {request.fill_mode_raw}",
                                 samps_read=0)
            if n >= 0 and request.array_size_in_samps < n * len(task.channels):
                raise DaqmxError(READ_BUFFER_TOO_SMALL,
                                 f"Required size: {n * len(task.channels)}\n"
                                 f"Buffer size: {request.array_size_in_samps}", samps_read=0)
            data, got, status = self.read_ai(task.name, n, request.timeout)
            flat = data.T.ravel() if request.fill_mode_raw == GROUP_BY_SCAN_NUMBER else data.ravel()
            return pb.ReadAnalogF64Response(
                status=status, read_array=flat.tolist(), samps_per_chan_read=got)

        return self._run(context, read)

    def ReadAnalogScalarF64(self, request: Any, context: Context) -> Any:
        def read() -> Any:
            task = self._task(request.task)
            if len(task.channels) != 1:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "A scalar read needs a task with "
                                 f"one channel; this one has {len(task.channels)}.")
            data, _ = self.device.read(task.name, 1, request.timeout)
            return pb.ReadAnalogScalarF64Response(value=float(data[0, 0]))

        return self._run(context, read)

    # --- events ------------------------------------------------------------------------------

    def RegisterEveryNSamplesEvent(self, request: Any, context: Context) -> Iterator[Any]:
        """Server stream: one response each time another N samples are in the buffer.

        The stream watches the clock and never drives it: on a virtual clock an event fires
        when a read, a sleep or ``advance`` of someone else has moved time past it.
        """
        kind = request.every_n_samples_event_type_raw
        name = request.task.name
        n = request.n_samples

        def register() -> int:
            self.device.task(name)
            if self.io_event_progress(name, kind) is not None:
                pass  # an AO task's transferred-from-buffer event (io_service)
            elif kind != ACQUIRED_INTO_BUFFER:
                raise DaqmxError(EVERY_N_SAMPS_TRANSFERRED_EVENT_NOT_SUPPORTED,
                                 f"Task Name: {name}\nEvent type: {kind}")
            if n < 1:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Every N samples: N = {n}")
            with self._event_lock:
                if name in self._events:
                    raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "An every N samples acquired into "
                                     f"buffer event is already registered for task {name}.")
                self._registrations += 1
                self._events[name] = self._registrations
                return self._registrations

        token = self._run(context, register)
        context.send_initial_metadata(())
        return self._every_n_stream(context, name, n, token)

    def _every_n_stream(self, context: Context, name: str, n: int, token: int) -> Iterator[Any]:
        sent, t0 = 0, None
        try:
            while context.is_active():
                with self._event_lock:
                    if self._events.get(name) != token:
                        return
                try:
                    task = self.device.task(name)
                except DaqmxError:
                    return
                progress = self.io_event_progress(name, TRANSFERRED_FROM_BUFFER)
                if progress is not None:  # an AO task: samples generated since its start
                    if progress[0] != t0:
                        sent, t0 = 0, progress[0]
                    elif progress[1] >= (sent + 1) * n:
                        sent += 1
                        yield pb.RegisterEveryNSamplesEventResponse(
                            every_n_samples_event_type_raw=TRANSFERRED_FROM_BUFFER, n_samples=n)
                        continue
                elif not task.running or not task.timing_set:
                    sent, t0 = 0, None
                elif t0 != task.t0:
                    sent, t0 = 0, task.t0
                elif self.device.total_acquired(name) >= (sent + 1) * n:
                    sent += 1
                    yield pb.RegisterEveryNSamplesEventResponse(
                        every_n_samples_event_type_raw=ACQUIRED_INTO_BUFFER, n_samples=n)
                    continue
                time.sleep(EVENT_POLL)
        finally:
            with self._event_lock:
                if self._events.get(name) == token:
                    del self._events[name]

    def UnregisterEveryNSamplesEvent(self, request: Any, context: Context) -> Any:
        with self._event_lock:
            self._events.pop(request.task.name, None)
        return pb.UnregisterEveryNSamplesEventResponse()


def _function_not_supported(rpc: str) -> Callable[..., Any]:
    def handler(self: Usb6001Servicer, request: Any, context: Context) -> Any:
        self._run(context, lambda: _raise(_no_function(rpc)))

    handler.__name__ = handler.__qualname__ = rpc
    handler.__doc__ = f"DAQmx{rpc}: not simulated; answers DAQmx -209876 naming it."
    return handler


def _attribute_handler(rpc: str) -> Callable[..., Any]:
    def handler(self: Usb6001Servicer, request: Any, context: Context) -> Any:
        return self._attribute(rpc, request, context)

    handler.__name__ = handler.__qualname__ = rpc
    handler.__doc__ = f"DAQmx{rpc}: served from the property table."
    return handler


def _raise(fault: DaqmxError) -> NoReturn:
    raise fault


def _complete_service() -> list[str]:
    """Give every RPC of the NiDAQmx service the servicer does not define a handler: the
    property table for attribute RPCs, a named DAQmx error for the rest. Returns the names."""
    base = pb_grpc.NiDAQmxServicer
    filled = []
    for method in pb.DESCRIPTOR.services_by_name["NiDAQmx"].methods:
        if getattr(Usb6001Servicer, method.name) is not getattr(base, method.name):
            continue
        if _ATTRIBUTE_RPC.match(method.name):
            setattr(Usb6001Servicer, method.name, _attribute_handler(method.name))
        else:
            setattr(Usb6001Servicer, method.name, _function_not_supported(method.name))
            filled.append(method.name)
    return filled


#: RPCs of the service the simulated USB-6001 answers with DAQmx -209876 (not simulated).
NOT_SIMULATED: tuple[str, ...] = tuple(_complete_service())
