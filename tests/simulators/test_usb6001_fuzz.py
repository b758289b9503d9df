"""The simulated USB-6001 gRPC server survives malformed requests: bytes that are no request
of the method, and requests of every simulated RPC (and of the property RPCs) with random
field values (NaN, infinities, extreme integers, odd names) each end with a gRPC status (a
DAQmx error, INTERNAL for bytes that do not decode, INVALID_ARGUMENT for fields that do not
convert, such as a waveform with both regular and irregular timing), never an unexplained
failure, and the official nidaqmx client still reads from the device afterwards."""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterator
from typing import Any

import grpc
import nidaqmx
import pytest
from google.protobuf.descriptor import Descriptor, FieldDescriptor
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nidaqmx._stubs import nidaqmx_pb2 as pb
from nidaqmx.constants import TerminalConfiguration
from session_pb2 import Session

from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.usb6001 import SimulatedUsb6001, start_server
from gelrig.simulators.usb6001.servicer import MAX_READ_VALUES, NOT_SIMULATED

SERVICE = pb.DESCRIPTOR.services_by_name["NiDAQmx"]
UNARY = [m for m in SERVICE.methods if not (m.server_streaming or m.client_streaming)]
SIMULATED = [m for m in UNARY if m.name not in NOT_SIMULATED
             and not re.match(r"^(Get|Set|Reset)\w+Attribute", m.name)]
PROPERTIES = [m for m in UNARY if re.match(r"^(Get|Set|Reset)\w+Attribute", m.name)]
#: Names a request may carry: the fuzz task's, the device's, its channels, and anything.
NAMES = st.one_of(st.sampled_from(["fuzz", "Dev1", "Dev1/ai0", "Dev1/ai0:1", "ai0", "",
                                   "Dev1/ai99", "fuzz,fuzz"]), st.text(max_size=20))
FT = FieldDescriptor

_INTS = {FT.TYPE_INT32: (-2**31, 2**31 - 1), FT.TYPE_SINT32: (-2**31, 2**31 - 1),
         FT.TYPE_SFIXED32: (-2**31, 2**31 - 1), FT.TYPE_UINT32: (0, 2**32 - 1),
         FT.TYPE_FIXED32: (0, 2**32 - 1), FT.TYPE_INT64: (-2**63, 2**63 - 1),
         FT.TYPE_SINT64: (-2**63, 2**63 - 1), FT.TYPE_SFIXED64: (-2**63, 2**63 - 1),
         FT.TYPE_UINT64: (0, 2**64 - 1), FT.TYPE_FIXED64: (0, 2**64 - 1),
         FT.TYPE_ENUM: (-2**31, 2**31 - 1)}
#: Numbers a device field is most likely to choke on, besides random ones.
_EDGES = [0, 1, -1, 2, 10, 100, 1000, 10**6, 10**9, 2**31 - 1, -2**31, 10348, 10083,
          10106, 10123, 10178, 10280, 10388, 10390, 10123, 10178, 1]


def scalar(field: FieldDescriptor) -> st.SearchStrategy[Any]:
    if field.type in (FT.TYPE_DOUBLE, FT.TYPE_FLOAT):
        return st.one_of(st.sampled_from([0.0, -1.0, 1.0, 10.0, 1e3, 1e300, math.nan,
                                          math.inf, -math.inf, 5e-324]),
                         st.floats(width=32 if field.type == FT.TYPE_FLOAT else 64))
    if field.type == FT.TYPE_BOOL:
        return st.booleans()
    if field.type == FT.TYPE_STRING:  # mostly the fuzz task's name: reach the device
        return st.one_of(st.just("fuzz"), st.just("fuzz"), NAMES)
    if field.type == FT.TYPE_BYTES:
        return st.binary(max_size=32)
    lo, hi = _INTS[field.type]
    return st.one_of(st.sampled_from([v for v in _EDGES if lo <= v <= hi]),
                     st.integers(lo, hi))


@st.composite
def message(draw: st.DrawFn, descriptor: Descriptor, depth: int = 0) -> Any:
    """A request of ``descriptor`` with some of its fields set to random values."""
    out = getattr(pb, descriptor.name)() if hasattr(pb, descriptor.name) else None
    if out is None:  # a message of another file (Session)
        from google.protobuf import message_factory

        out = message_factory.GetMessageClass(descriptor)()
    for field in descriptor.fields:
        if field.type != FT.TYPE_MESSAGE and not draw(st.integers(0, 3)):
            continue  # left at its default
        if field.type == FT.TYPE_MESSAGE:
            if depth > 1:
                continue
            values = [draw(message(field.message_type, depth + 1))
                      for _ in range(draw(st.integers(1, 2)) if field.is_repeated
                                     else 1)]
            if field.message_type.GetOptions().map_entry:  # a map: entries by key
                container = getattr(out, field.name)
                for entry in values:
                    if field.message_type.fields_by_name["value"].type == FT.TYPE_MESSAGE:
                        container[entry.key].CopyFrom(entry.value)
                    else:
                        container[entry.key] = entry.value
            elif field.is_repeated:
                getattr(out, field.name).extend(values)
            else:
                getattr(out, field.name).CopyFrom(values[0])
        elif field.is_repeated:
            getattr(out, field.name).extend(draw(st.lists(scalar(field), max_size=3)))
        else:
            setattr(out, field.name, draw(scalar(field)))
    return out


def counts(*typical: int, signed: bool = True) -> st.SearchStrategy[int]:
    """Small counts, the typical ones, and the largest the field holds."""
    big = [2**31 - 1, MAX_READ_VALUES] if signed else [2**64 - 1, 2**31, MAX_READ_VALUES]
    return st.one_of(st.sampled_from(typical), st.integers(-2 if signed else 0, 5000),
                     st.sampled_from(big))


times = st.sampled_from([0.0, 0.01, 1.0, 10.0, -1.0, math.nan, math.inf, 1e300, -5.0])


@st.composite
def plausible(draw: st.DrawFn) -> tuple[str, bytes]:
    """A request of the acquisition path with values near what a client sends, so that the
    device's own checks (not only the name lookup) meet the edges."""
    which = draw(st.sampled_from(["timing", "read", "start", "stop", "wait", "control"]))
    task = Session(name="fuzz")
    if which == "timing":
        request: Any = pb.CfgSampClkTimingRequest(
            task=task, rate=draw(st.one_of(times, st.floats(1.0, 20000.0))),
            sample_mode_raw=draw(st.sampled_from([10123, 10178, 0, -1])),
            samps_per_chan=draw(counts(100, 1000, signed=False)), active_edge_raw=draw(
                st.sampled_from([0, 10280, 10171])), source=draw(st.sampled_from(
                    ["", "OnboardClock", "/Dev1/PFI0"])))
        return "CfgSampClkTiming", request.SerializeToString()
    if which == "read":
        n = draw(counts(-1, 0, 1, 10, 100))
        request = pb.ReadAnalogF64Request(
            task=task, num_samps_per_chan=n, timeout=draw(times),
            fill_mode_raw=draw(st.sampled_from([0, 1, 2])),
            array_size_in_samps=draw(st.sampled_from([max(0, 2 * n), 0, 2**32 - 1])))
        return "ReadAnalogF64", request.SerializeToString()
    if which == "wait":
        request = pb.WaitUntilTaskDoneRequest(task=task, time_to_wait=draw(times))
        return "WaitUntilTaskDone", request.SerializeToString()
    if which == "control":
        request = pb.TaskControlRequest(task=task, action_raw=draw(st.integers(-1, 7)))
        return "TaskControl", request.SerializeToString()
    name = "StartTask" if which == "start" else "StopTask"
    return name, getattr(pb, f"{name}Request")(task=task).SerializeToString()


@st.composite
def calls(draw: st.DrawFn) -> tuple[str, bytes]:
    """(method, serialized request): a plausible request of the acquisition path, a random
    request of a simulated or property RPC, or bytes that may not decode at all."""
    if draw(st.booleans()):
        return draw(plausible())
    method = draw(st.one_of(st.sampled_from(SIMULATED), st.sampled_from(PROPERTIES)))
    if draw(st.integers(0, 4)) == 0:
        return method.name, draw(st.binary(max_size=64))
    return method.name, draw(message(method.input_type)).SerializeToString()


class Served:
    def __init__(self) -> None:
        self.clock = VirtualClock()
        self.device = SimulatedUsb6001(self.clock)
        self.server = start_server(self.device)
        self.channel = self.server.channel()

    def call(self, method: str, data: bytes) -> grpc.StatusCode:
        rpc = self.channel.unary_unary(f"/{SERVICE.full_name}/{method}",
                                       request_serializer=None, response_deserializer=None)
        try:
            rpc(data, timeout=10.0)
        except grpc.RpcError as exc:
            return exc.code()  # type: ignore[no-any-return, attr-defined]
        return grpc.StatusCode.OK

    def reads(self) -> bool:
        """The fuzz task cleared over the wire (it may hold the device's AI), the official
        client reads a sample from the device."""
        clear = pb.ClearTaskRequest(task=Session(name="fuzz")).SerializeToString()
        assert self.call("ClearTask", clear) in (grpc.StatusCode.OK, grpc.StatusCode.UNKNOWN)
        assert not self.device.has_task("fuzz")
        options = nidaqmx.GrpcSessionOptions(grpc_channel=self.channel, session_name="")
        with nidaqmx.Task(grpc_options=options) as task:
            task.ai_channels.add_ai_voltage_chan("Dev1/ai0", min_val=-10.0, max_val=10.0,
                                                 terminal_config=TerminalConfiguration.RSE)
            return math.isfinite(task.read())

    def close(self) -> None:
        self.channel.close()
        self.server.stop()


@pytest.fixture(scope="module")
def served() -> Iterator[Served]:
    s = Served()
    yield s
    s.close()


def fuzz_task(served: Served) -> None:
    """A task named ``fuzz`` with a channel, so that random requests reach the device."""
    dev = served.device
    if dev.has_task("fuzz"):
        dev.clear_task("fuzz")
    dev.create_task("fuzz")
    dev.add_voltage_channel("fuzz", "Dev1/ai0:1", "", 10083, -10.0, 10.0, 10348)


@settings(max_examples=250, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(sequence=st.lists(calls(), min_size=1, max_size=8))
def test_malformed_requests_end_in_a_status_and_the_server_serves_on(
        served: Served, sequence: list[tuple[str, bytes]], caplog: pytest.LogCaptureFixture
) -> None:
    fuzz_task(served)
    caplog.clear()  # the fixture lives across examples: judge this sequence alone
    with caplog.at_level(logging.ERROR, logger="gelrig.simulators.usb6001"):
        for method, data in sequence:
            code = served.call(method, data)
            assert code in (grpc.StatusCode.OK, grpc.StatusCode.UNKNOWN,  # DAQmx errors
                            grpc.StatusCode.INTERNAL,  # bytes that do not decode
                            grpc.StatusCode.INVALID_ARGUMENT,  # fields that do not convert
                            grpc.StatusCode.NOT_FOUND, grpc.StatusCode.ALREADY_EXISTS), \
                (method, data, code)
    # every failure is one the device explains (a DAQmx error), none a handler's crash
    assert not [r for r in caplog.records if r.name == "gelrig.simulators.usb6001"], \
        caplog.text
    assert served.reads()


def test_a_read_too_large_for_one_reply_is_refused_before_allocating(served: Served) -> None:
    fuzz_task(served)
    request = pb.ReadAnalogF64Request(num_samps_per_chan=MAX_READ_VALUES,
                                      array_size_in_samps=2**32 - 1, timeout=0.0,
                                      fill_mode_raw=0)
    request.task.name = "fuzz"
    rpc = served.channel.unary_unary(f"/{SERVICE.full_name}/ReadAnalogF64",
                                     request_serializer=None, response_deserializer=None)
    with pytest.raises(grpc.RpcError) as info:
        rpc(request.SerializeToString(), timeout=10.0)
    assert info.value.code() == grpc.StatusCode.UNKNOWN  # type: ignore[attr-defined]
    metadata = dict(info.value.trailing_metadata())  # type: ignore[attr-defined]
    assert metadata["ni-error"] == "-200077"
    assert f"at most {MAX_READ_VALUES} values per read" in info.value.details()  # type: ignore[attr-defined]
    assert served.reads()


def test_a_failing_handler_is_logged_and_answered_internal(
        served: Served, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def broken(*args: object) -> None:
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(served.device, "is_done", broken)
    fuzz_task(served)
    request = pb.IsTaskDoneRequest()
    request.task.name = "fuzz"
    with caplog.at_level(logging.ERROR):
        code = served.call("IsTaskDone", request.SerializeToString())
    assert code == grpc.StatusCode.INTERNAL
    assert "a request failed" in caplog.text
    monkeypatch.undo()
    assert served.reads()


def test_a_waveform_with_both_timings_is_an_invalid_argument_not_a_crash(
        served: Served, caplog: pytest.LogCaptureFixture) -> None:
    """Found by the fuzz test in CI: a waveform message with ``timestamps`` beside ``dt`` made
    the handler raise ValueError, logged as a crash of the server."""
    fuzz_task(served)
    request = pb.WriteAnalogWaveformsRequest()
    request.task.name = "fuzz"
    wave = request.waveforms.add()
    wave.y_data.extend([0.0, 1.0])
    wave.dt = 0.001
    wave.timestamps.add()
    wave.timestamps.add()
    with caplog.at_level(logging.ERROR, logger="gelrig.simulators.usb6001"):
        code = served.call("WriteAnalogWaveforms", request.SerializeToString())
    assert code == grpc.StatusCode.INVALID_ARGUMENT
    assert not [r for r in caplog.records if r.name == "gelrig.simulators.usb6001"]
    assert served.reads()
