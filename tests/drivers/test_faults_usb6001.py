"""USB-6001 over gRPC against a served simulator: every fault is a typed error within the
call's deadline (ADR 0060), and a session left by a killed process is reclaimed (ADR 0061)."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import grpc
import nidaqmx
import pytest
from nidaqmx._stubs import nidaqmx_pb2 as pb
from nidaqmx._stubs import nidaqmx_pb2_grpc as pb_grpc
from nidaqmx.constants import AcquisitionType

from gelrig.drivers.usb6001 import Usb6001ForceSensor
from gelrig.drivers.usb6001.config import Usb6001Config
from gelrig.drivers.usb6001.deadline import DeadlineInterceptor, with_deadlines
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.clock import RealClock
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    FramingError,
    InstrumentTimeout,
)
from tests.faultproxy import FaultProxy, failing
from tests.served import ROOT, Served, serve

RATE = 1000.0
N = 50  # samples per block: 50 ms
CONFIG = Usb6001Config(read_margin=0.5, call_timeout=1.0)
READ_DEADLINE = N / RATE + CONFIG.read_margin + CONFIG.call_timeout
SLACK = 1.5


@pytest.fixture(scope="module")
def server() -> Iterator[Served]:
    with serve("usb6001", duration=300) as s:
        yield s


@pytest.fixture
def own_server() -> Iterator[Served]:
    with serve("usb6001", duration=120) as s:
        yield s


def sensor_at(port: int, config: Usb6001Config = CONFIG) -> Usb6001ForceSensor:
    return Usb6001ForceSensor(f"grpc://127.0.0.1:{port}", config, LoadCellChain(), RealClock())



def test_the_interceptor_bounds_each_call_and_adds_a_reads_own_wait() -> None:
    guard = DeadlineInterceptor(2.0)
    assert guard.timeout_for(object()) == 2.0
    read = pb.ReadAnalogF64Request(timeout=3.5)
    assert guard.timeout_for(read) == pytest.approx(5.5)
    with guard.budget(0.5):
        assert guard.timeout_for(read) <= 0.5
        with guard.budget(10.0):
            assert guard.timeout_for(read) <= 0.5  # the tighter budget holds
    assert guard.timeout_for(read) == pytest.approx(5.5)
    with pytest.raises(ValueError):
        DeadlineInterceptor(0.0)


def test_a_silent_server_is_a_timeout_within_the_deadline() -> None:
    """A listener that accepts and never answers: a bare channel would wait for ever."""
    import socket

    with socket.socket() as mute:
        mute.bind(("127.0.0.1", 0))
        mute.listen(1)
        guard = DeadlineInterceptor(0.5)
        channel = with_deadlines(grpc.insecure_channel(f"127.0.0.1:{mute.getsockname()[1]}"),
                                 guard)
        stub = pb_grpc.NiDAQmxStub(channel)
        t0 = time.monotonic()
        with pytest.raises(grpc.RpcError) as info:
            stub.GetSystemInfoAttributeUInt32(
                pb.GetSystemInfoAttributeUInt32Request(
                    attribute_raw=0x1272))
        assert info.value.code() == grpc.StatusCode.DEADLINE_EXCEEDED  # type: ignore[attr-defined]
        assert time.monotonic() - t0 < 0.5 + SLACK
        channel.close()


def test_sigstop_mid_acquisition_is_a_timeout_within_the_read_deadline(
        own_server: Served) -> None:
    with sensor_at(own_server.port) as sensor:
        sensor.start(RATE)
        assert len(sensor.read_block(N)) == N
        own_server.pause()
        try:
            exc, took = failing(lambda: sensor.read_block(N), InstrumentTimeout)
            assert took < READ_DEADLINE + SLACK, took
            assert "did not answer in time" in str(exc)
        finally:
            own_server.resume()
        sensor.start(RATE)  # restart: the sample count is known again
        assert len(sensor.read_block(N)) == N


def test_open_on_a_frozen_server_is_a_timeout_within_one_budget(own_server: Served) -> None:
    own_server.pause()
    try:
        _, took = failing(lambda: sensor_at(own_server.port).open(), InstrumentTimeout)
    finally:
        own_server.resume()
    assert took < 2 * CONFIG.call_timeout + SLACK, took


def test_killed_server_is_a_disconnection_within_the_deadline(own_server: Served) -> None:
    sensor = sensor_at(own_server.port).open()
    sensor.start(RATE)
    sensor.read_block(N)
    own_server.kill()
    _, took = failing(lambda: sensor.read_block(N), (Disconnected, InstrumentTimeout))
    assert took < READ_DEADLINE + SLACK, took
    t0 = time.monotonic()
    sensor.close()  # nothing to talk to: bounded, no error escapes
    assert time.monotonic() - t0 < CONFIG.call_timeout + SLACK


@pytest.mark.parametrize(("fault", "errors"), [
    ("swallow", InstrumentTimeout),
    ("garbage", (Disconnected, FramingError, InstrumentTimeout)),
    ("truncate", (Disconnected, FramingError, InstrumentTimeout)),
    ("close", Disconnected),
])
def test_wire_faults_are_typed_errors_within_the_deadline(
        server: Served, fault: str, errors: type[Exception] | tuple[type[Exception], ...]
) -> None:
    with FaultProxy(server.port, lifetime=60) as proxy:
        sensor = sensor_at(proxy.port).open()
        try:
            sensor.start(RATE)
            sensor.read_block(N)
            getattr(proxy, fault)()
            _, took = failing(lambda: sensor.read_block(N), errors)
            assert took < READ_DEADLINE + SLACK, (fault, took)
        finally:
            t0 = time.monotonic()
            sensor.close()  # bounded, and no error escapes it
            assert time.monotonic() - t0 < CONFIG.call_timeout + SLACK
        proxy.heal()
        # Recovers: a new driver instance takes over the session on the server.
        with sensor_at(proxy.port) as again:
            again.start(RATE)
            assert len(again.read_block(N)) == N


def test_a_delay_shorter_than_the_deadline_is_only_slow(server: Served) -> None:
    with FaultProxy(server.port, lifetime=60) as proxy, sensor_at(proxy.port) as sensor:
        sensor.start(RATE)
        proxy.delay(0.3)
        t0 = time.monotonic()
        assert len(sensor.read_block(N)) == N
        assert time.monotonic() - t0 >= 0.3
        proxy.delay(READ_DEADLINE + 1.0)
        _, took = failing(lambda: sensor.read_block(N), InstrumentTimeout)
        assert took < READ_DEADLINE + SLACK


# ---- a session left by a killed process (ADR 0061) ----------------------------------------
_HOLDER = """
import sys, time
from gelrig.drivers.usb6001 import Usb6001ForceSensor
from gelrig.drivers.usb6001.config import Usb6001Config
from gelrig.instrument.core.clock import RealClock
from gelrig.instrument.contracts.loadcell import LoadCellChain
sensor = Usb6001ForceSensor(sys.argv[1], Usb6001Config(), LoadCellChain(), RealClock()).open()
sensor.start(1000.0)
sensor.read_block(10)
print("holding", flush=True)
time.sleep(60)
"""


def test_a_session_left_by_a_killed_process_is_reclaimed(own_server: Served) -> None:
    address = f"grpc://127.0.0.1:{own_server.port}"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, address], cwd=ROOT, text=True,
                              stdout=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert holder.stdout is not None
        ready, _, _ = select.select([holder.stdout], [], [], 30)
        assert ready and holder.stdout.readline().strip() == "holding"
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
        if holder.stdout:
            holder.stdout.close()
    with sensor_at(own_server.port) as sensor:  # the same device on the same server
        assert sensor.reclaimed
        sensor.start(RATE)  # was DAQmx -50103 (the device is reserved) before reclaim
        assert len(sensor.read_block(N)) == N
    with sensor_at(own_server.port) as sensor:  # closed cleanly: nothing left to reclaim
        assert not sensor.reclaimed


def test_a_foreign_task_holding_the_device_names_the_server_to_restart(
        own_server: Served) -> None:
    with grpc.insecure_channel(f"127.0.0.1:{own_server.port}") as channel:
        other = nidaqmx.Task(grpc_options=nidaqmx.GrpcSessionOptions(channel, ""))
        try:
            other.ai_channels.add_ai_voltage_chan("Dev1/ai1", min_val=-10.0, max_val=10.0)
            other.timing.cfg_samp_clk_timing(RATE, sample_mode=AcquisitionType.CONTINUOUS)
            other.start()
            with sensor_at(own_server.port) as sensor:
                exc, _ = failing(lambda: sensor.start(RATE), DeviceErrorReply)
            text = str(exc)
            assert "-50103" in text and f"127.0.0.1:{own_server.port}" in text
            assert "restart" in text and "gelrig sim serve usb6001" in text
        finally:
            other.close()

