"""HIL: the official nidaqmx client, over real gRPC, against the simulated USB-6001."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import grpc
import nidaqmx
import numpy as np
import pytest
from nidaqmx.constants import AcquisitionType, TerminalConfiguration
from nidaqmx.stream_readers import AnalogMultiChannelReader, AnalogSingleChannelReader

from gelrig.instrument.core.clock import Clock, PacedClock, VirtualClock
from gelrig.simulators.usb6001 import (
    DeviceSpec,
    RunningServer,
    SampleCounterSignal,
    SimulatedUsb6001,
    start_server,
)
from gelrig.simulators.usb6001 import serve as serve_module

LSB = DeviceSpec().lsb
ROOT = Path(__file__).resolve().parents[2]


def options(channel: grpc.Channel) -> nidaqmx.GrpcSessionOptions:
    return nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name="")


class Rig:
    """A served device with counter patterns on ai0 and ai1 and a client channel."""

    def __init__(self, clock: Clock, buffer_size: int | None = None):
        self.clock = clock
        self.c0 = SampleCounterSignal(LSB, period=8000)
        self.c1 = SampleCounterSignal(LSB, period=5000)
        self.device = SimulatedUsb6001(clock, {"ai0": self.c0, "ai1": self.c1},
                                       buffer_size=buffer_size)
        self.server: RunningServer = start_server(self.device)
        self.channel = self.server.channel()

    def task(self) -> nidaqmx.Task:
        return nidaqmx.Task(grpc_options=options(self.channel))

    def close(self) -> None:
        self.channel.close()
        self.server.stop()


@pytest.fixture
def rig() -> Iterator[Rig]:
    r = Rig(VirtualClock())
    yield r
    r.close()


def add_chan(task: nidaqmx.Task, chans: str = "Dev1/ai0") -> None:
    task.ai_channels.add_ai_voltage_chan(
        chans, terminal_config=TerminalConfiguration.RSE, min_val=-10.0, max_val=10.0)


def assert_consecutive(k: np.ndarray, period: int) -> None:
    steps = np.mod(np.diff(k), period)
    assert np.all(steps == 1), f"lost or repeated samples at {np.flatnonzero(steps != 1)[:5]}"


@pytest.mark.parametrize("rate", [100.0, 1000.0])
def test_official_client_reads_every_sample_once(rig: Rig, rate: float) -> None:
    with rig.task() as task:
        add_chan(task)
        task.timing.cfg_samp_clk_timing(rate, sample_mode=AcquisitionType.CONTINUOUS,
                                        samps_per_chan=int(rate * 10))
        task.start()
        reader = AnalogSingleChannelReader(task.in_stream)
        values = []
        for n in (1, 37, 100, int(rate), 999, int(rate * 5)):
            buf = np.empty(n)
            assert reader.read_many_sample(buf, n, timeout=n / rate + 1.0) == n
            values.append(buf.copy())
        values.append(np.asarray(task.read(number_of_samples_per_channel=250)))
        total = sum(v.size for v in values)
        assert rig.clock.now() == pytest.approx((total - 1) / rate)
        k = rig.c0.decode(np.concatenate(values))
        assert k[0] == 0  # sample 0 first
        assert_consecutive(k, rig.c0.period)
        assert task.in_stream.total_samp_per_chan_acquired == total


def test_two_channels_in_channel_order(rig: Rig) -> None:
    with rig.task() as task:
        add_chan(task, "Dev1/ai0:1")
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        task.start()
        reader = AnalogMultiChannelReader(task.in_stream)
        chunks = []
        for _ in range(3):
            chunk = np.empty((2, 4000))
            reader.read_many_sample(chunk, 4000, timeout=10.0)
            chunks.append(chunk)
        data = np.concatenate(chunks, axis=1)
        assert_consecutive(rig.c0.decode(data[0]), 8000)
        assert_consecutive(rig.c1.decode(data[1]), 5000)
        assert rig.c1.decode(data[1])[-1] == (11_999 % 5000)
        # task.read groups by scan for several channels: same samples, per channel.
        rows = np.asarray(task.read(number_of_samples_per_channel=10))
        assert rig.c0.decode(rows[0])[0] == 12_000 % 8000
        assert rig.c1.decode(rows[1])[0] == 12_000 % 5000


def test_device_properties_through_the_client(rig: Rig) -> None:
    with rig.task() as task:
        add_chan(task)
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS,
                                        samps_per_chan=2000)
        device = task.devices[0]
        assert device.name == "Dev1"
        assert device.product_type == "USB-6001"
        assert device.serial_num == DeviceSpec().serial
        assert task.timing.samp_clk_max_rate == pytest.approx(20_000.0)
        chan = task.ai_channels[0]
        assert chan.ai_term_cfg == TerminalConfiguration.RSE
        assert (chan.ai_min, chan.ai_max) == (-10.0, 10.0)
        task.start()
        assert task.in_stream.input_buf_size == 10_000  # DAQmx's rule beats a smaller request
        assert task.in_stream.avail_samp_per_chan == 1


def test_overflow_reaches_the_client_as_a_read_error(rig: Rig) -> None:
    with rig.task() as task:
        add_chan(task)
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        task.start()
        assert isinstance(rig.clock, VirtualClock)
        rig.clock.advance(10.5)  # 10 500 unread > the 10 kS buffer
        with pytest.raises(nidaqmx.errors.DaqReadError) as info:
            task.read(number_of_samples_per_channel=10)
        assert info.value.error_code == -200279
        assert "keep up" in str(info.value)


def test_timeout_delivers_partial_samples(rig: Rig) -> None:
    with rig.task() as task:
        add_chan(task)
        task.timing.cfg_samp_clk_timing(100.0, sample_mode=AcquisitionType.CONTINUOUS)
        task.start()
        reader = AnalogSingleChannelReader(task.in_stream)
        buf = np.full(1000, np.nan)
        with pytest.raises(nidaqmx.errors.DaqReadError) as info:
            reader.read_many_sample(buf, 1000, timeout=2.0)
        assert info.value.error_code == -200284
        assert info.value.samps_per_chan_read == 201
        assert_consecutive(rig.c0.decode(buf[:201]), 8000)


def test_wrong_device_and_unsupported_calls(rig: Rig) -> None:
    with rig.task() as task:
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            add_chan(task, "Dev7/ai0")
        assert info.value.error_code == -200220
        with pytest.raises(nidaqmx.errors.DaqError) as unsupported:
            task.ai_channels.add_ai_accel_chan("Dev1/ai0")
        assert unsupported.value.error_code == -200431  # no IEPE input on a 6001
        assert "DAQmxCreateAIAccelChan" in str(unsupported.value)


def test_paced_time_samples_accrue_with_the_clock() -> None:
    """Real concurrency: reading what is available as it accrues loses nothing."""
    r = Rig(PacedClock(20.0))
    try:
        with r.task() as task:
            add_chan(task)
            task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
            task.start()
            chunks = []
            end = time.monotonic() + 0.4
            while time.monotonic() < end:
                time.sleep(0.02)
                chunks.append(np.atleast_1d(np.asarray(
                    task.read(number_of_samples_per_channel=nidaqmx.constants.READ_ALL_AVAILABLE))))
            k = r.c0.decode(np.concatenate(chunks))
            assert k.size > 4000  # about 8 s of virtual time at 20x
            assert_consecutive(k, 8000)
    finally:
        r.close()


def _serve_args(**overrides: object) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    serve_module.add_arguments(parser)
    args = parser.parse_args(["--port", "0", "--clock", "paced:50"])
    for key, value in overrides.items():
        setattr(args, key, value)
    return args


def test_serve_run_prints_where_it_listens(capsys: pytest.CaptureFixture[str]) -> None:
    stop = threading.Event()
    result: list[int] = []
    worker = threading.Thread(target=lambda: result.append(serve_module.run(_serve_args(), stop)))
    worker.start()
    try:
        for _ in range(200):
            out = capsys.readouterr().out
            if "listening" in out:
                break
            time.sleep(0.01)
        match = re.search(r"grpc://([\d.]+):(\d+)", out)
        assert match, out
        with grpc.insecure_channel(f"{match[1]}:{match[2]}") as channel, \
                nidaqmx.Task(grpc_options=options(channel)) as task:
            add_chan(task)
            task.timing.cfg_samp_clk_timing(100.0, sample_mode=AcquisitionType.CONTINUOUS)
            task.start()
            volts = np.asarray(task.read(number_of_samples_per_channel=20, timeout=5.0))
            # The plate stands still away from the sphere: the conditioner's offset only.
            assert np.mean(volts) == pytest.approx(0.0123, abs=0.002)
    finally:
        stop.set()
        worker.join(5)
    assert result == [0]


def test_gelrig_cli_serves_usb6001() -> None:
    """``gelrig sim serve usb6001`` in its own process, read by the official client."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(
        [sys.executable, "-m", "gelrig.cli", "sim", "serve", "usb6001", "--port", "0",
         "--clock", "paced:100", "--ramp-speed", "1 mm/s", "--plate-start", "1.9 mm"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        match = re.search(r"grpc://([\d.]+):(\d+)", line)
        assert match, line + (proc.stderr.read() if proc.stderr and proc.poll() else "")
        with grpc.insecure_channel(f"{match[1]}:{match[2]}") as channel, \
                nidaqmx.Task(grpc_options=options(channel)) as task:
            add_chan(task)
            task.timing.cfg_samp_clk_timing(100.0, sample_mode=AcquisitionType.CONTINUOUS)
            task.start()
            volts = np.asarray(task.read(number_of_samples_per_channel=300, timeout=10.0))
        # At 100x the plate reached 6 % in 12 ms of wall time: the hold force (69-75 mN at
        # 4 V/N) on the conditioner's 12.3 mV offset.
        assert 0.28 < float(np.mean(volts)) < 0.32
    finally:
        proc.terminate()
        proc.wait(10)
        if proc.stdout:
            proc.stdout.close()
        if proc.stderr:
            proc.stderr.close()
