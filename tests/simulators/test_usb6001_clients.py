"""An NI user's own nidaqmx scripts, written as NI's examples are, against the served simulator.

Each test is a script in the style of the nidaqmx examples (analog_in/voltage_acq_int_clk.py,
cont_voltage_acq_int_clk.py, ...): only the ``grpc_options`` say that the device is remote.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator

import nidaqmx
import numpy as np
import pytest
from nidaqmx.constants import (
    READ_ALL_AVAILABLE,
    AcquisitionType,
    BusType,
    OverwriteMode,
    ProductCategory,
    ReadRelativeTo,
    SampleTimingType,
)
from nidaqmx.stream_readers import AnalogSingleChannelReader

from gelrig.instrument.core.clock import Clock, PacedClock, VirtualClock
from gelrig.simulators.usb6001 import (
    ConstantSignal,
    DeviceSpec,
    RunningServer,
    SampleCounterSignal,
    SimulatedUsb6001,
    start_server,
)
from gelrig.simulators.usb6001.device import DOCUMENTED, DaqTiming
from gelrig.simulators.usb6001.rig import compression_daq
from gelrig.simulators.usb6001.servicer import NOT_SIMULATED, Usb6001Servicer

LSB = DeviceSpec().lsb
LEVEL = 2.5


class Served:
    """The simulator on a gRPC port: a sample counter on ai0, 2.5 V on ai1."""

    def __init__(self, clock: Clock, timing: str = "ideal"):
        self.clock = clock
        self.counter = SampleCounterSignal(LSB, period=8000)
        # the documented timing (ADR 0242): 100 ppm drift, 32-sample USB transfers, latency
        spec = DeviceSpec(timing=DOCUMENTED if timing == "documented" else DaqTiming())
        self.timing = spec.timing
        device = SimulatedUsb6001(clock, {"ai0": self.counter, "ai1": ConstantSignal(LEVEL)},
                                  spec=spec)
        self.server: RunningServer = start_server(device)
        self.channel = self.server.channel()
        self.options = nidaqmx.GrpcSessionOptions(grpc_channel=self.channel, session_name="")

    def close(self) -> None:
        self.channel.close()
        self.server.stop()


@pytest.fixture(params=["ideal", "documented"])
def sim(request: pytest.FixtureRequest) -> Iterator[Served]:
    served = Served(VirtualClock(), request.param)
    yield served
    served.close()


def counts(sim: Served, volts: object) -> np.ndarray:
    return np.asarray(sim.counter.decode(np.asarray(volts)))


def assert_consecutive(k: np.ndarray) -> None:
    assert np.all(np.mod(np.diff(k), 8000) == 1), "lost or repeated samples"


def test_on_demand_read_returns_fresh_samples(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("dev1/ai1")  # device names are not case sensitive
        value = task.read()
        assert abs(value - LEVEL) <= LSB
        assert len(task.read(number_of_samples_per_channel=5)) == 5
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        first = counts(sim, task.read())
        assert isinstance(sim.clock, VirtualClock)
        sim.clock.advance(1.0)
        later = counts(sim, task.read())
        assert later != first  # sampled now, not a stale value


def test_on_demand_read_one_sample_and_explicit_start(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai1")
        assert task.timing.samp_timing_type == SampleTimingType.ON_DEMAND
        task.start()
        reader = AnalogSingleChannelReader(task.in_stream)
        assert abs(reader.read_one_sample() - LEVEL) <= LSB
        task.stop()


def test_finite_acquisition_reads_all_and_is_done(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.FINITE,
                                        samps_per_chan=100)
        data = task.read(READ_ALL_AVAILABLE)  # not started: the read starts it
        assert len(data) == 100
        assert_consecutive(counts(sim, data))
        assert task.is_task_done()
        assert task.timing.samp_timing_type == SampleTimingType.SAMPLE_CLOCK


def test_finite_acquisition_wait_until_done(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.FINITE,
                                        samps_per_chan=500)
        task.start()
        assert not task.is_task_done()
        t0 = sim.clock.now()
        task.wait_until_done(timeout=10.0)
        # done when the last sample (0.499 s on the device's clock) has reached the host: a
        # USB transfer's latency and jitter after it (none on the ideal device)
        tm = sim.timing
        last = 0.499 / (1 + tm.drift_ppm * 1e-6) + tm.latency
        assert last - 1e-9 <= sim.clock.now() - t0 <= last + tm.jitter + 1e-9
        assert task.is_task_done()
        data = task.read(READ_ALL_AVAILABLE)
        assert len(data) == 500
        task.stop()


@pytest.mark.parametrize("mode", [AcquisitionType.FINITE, AcquisitionType.CONTINUOUS])
def test_wait_until_done_times_out_with_the_daqmx_error(sim: Served, mode: AcquisitionType
                                                        ) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.timing.cfg_samp_clk_timing(10.0, sample_mode=mode, samps_per_chan=1000)
        task.start()
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            task.wait_until_done(timeout=1.0)
        assert info.value.error_code == -200560
        assert not task.is_task_done()


def test_continuous_acquisition_with_a_stream_reader(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        reader = AnalogSingleChannelReader(task.in_stream)
        task.start()
        blocks = []
        for _ in range(10):
            buf = np.zeros(100)
            assert reader.read_many_sample(buf, 100, timeout=10.0) == 100
            blocks.append(buf)
        k = counts(sim, np.concatenate(blocks))
        assert k[0] == 0  # the first sample of the acquisition (started at t = 0)
        assert_consecutive(k)


def test_overwrite_and_read_the_most_recent_samples(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        task.in_stream.input_buf_size = 1000
        task.in_stream.overwrite = OverwriteMode.OVERWRITE_UNREAD_SAMPLES
        task.in_stream.relative_to = ReadRelativeTo.MOST_RECENT_SAMPLE
        task.in_stream.offset = -10
        assert task.in_stream.input_buf_size == 1000
        assert task.in_stream.overwrite == OverwriteMode.OVERWRITE_UNREAD_SAMPLES
        assert task.in_stream.relative_to == ReadRelativeTo.MOST_RECENT_SAMPLE
        assert task.in_stream.offset == -10
        task.start()
        assert isinstance(sim.clock, VirtualClock)
        sim.clock.advance(5.0)  # 5001 samples into a 1000-sample buffer: overwritten, no error
        latest = counts(sim, task.read(number_of_samples_per_channel=10))
        # the latest samples that reached the host: on the ideal device 4991..5000; with USB
        # transfers, up to a transfer and its latency and jitter fewer (the drift's few more)
        tm = sim.timing
        late = tm.transfer + math.ceil((tm.latency + tm.jitter) * 1000.0)
        end = int(latest[-1]) + 1
        assert list(latest) == list(range(end - 10, end))
        assert 5001 - (late if late > 1 else 0) <= end <= \
            5001 + math.ceil(5.0 * 1000.0 * tm.drift_ppm * 1e-6)
        task.in_stream.relative_to = ReadRelativeTo.FIRST_SAMPLE
        task.in_stream.offset = 0
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            task.read(number_of_samples_per_channel=10)  # sample 0 was overwritten long ago
        assert info.value.error_code == -200279


def test_auto_start_off_refuses_a_read_of_a_stopped_task(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.in_stream.auto_start = False
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            task.read()
        assert info.value.error_code == -200473


def test_device_and_system_attributes(sim: Served) -> None:
    device = nidaqmx.system.Device("dev1", grpc_options=sim.options)
    assert device.product_type == "USB-6001"
    assert device.ai_voltage_rngs == [-10.0, 10.0]
    assert device.ai_max_single_chan_rate == 20_000.0
    assert device.ai_max_multi_chan_rate == 20_000.0
    assert device.bus_type == BusType.USB
    assert device.product_category == ProductCategory.USBDAQ
    assert device.is_simulated is True
    assert [c.name for c in device.ai_physical_chans] == [f"Dev1/ai{i}" for i in range(8)]
    assert "/Dev1/PFI0" in device.terminals
    device.self_test_device()
    system = nidaqmx.system.System(grpc_options=sim.options)
    assert [d.name for d in system.devices] == ["Dev1"]
    assert list(system.tasks) == []
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        task.start()
        device.reset_device()  # aborts the running task
        assert task.is_task_done()


def test_timing_and_channel_attributes(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        chan = task.ai_channels.add_ai_voltage_chan("Dev1/ai3", name_to_assign_to_channel="force")
        assert chan.physical_channel.name == "Dev1/ai3"
        chan.description = "load cell"
        assert chan.description == "load cell"
        assert task.timing.samp_clk_src == "OnboardClock"
        task.timing.samp_clk_src = "OnboardClock"
        with pytest.raises(nidaqmx.errors.DaqError) as lowpass:
            _ = chan.ai_lowpass_enable
        assert lowpass.value.error_code == -200452
        with pytest.raises(nidaqmx.errors.DaqError) as source:
            task.timing.samp_clk_src = "/Dev1/PFI0"
        assert source.value.error_code == -200077


@pytest.mark.parametrize("timing", ["ideal", "documented"])
def test_every_n_samples_event(timing: str) -> None:
    sim = Served(PacedClock(20.0), timing)
    got: list[np.ndarray] = []
    enough = threading.Event()
    try:
        with nidaqmx.Task(grpc_options=sim.options) as task:
            task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
            task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)

            def callback(handle: object, event_type: int, n: int, data: object) -> int:
                got.append(np.asarray(task.read(number_of_samples_per_channel=n)))
                if len(got) >= 3:
                    enough.set()
                return 0

            task.register_every_n_samples_acquired_into_buffer_event(200, callback)
            task.start()
            assert enough.wait(timeout=10.0), "no every-N-samples events"
            task.stop()
        assert all(block.size == 200 for block in got[:3])
        assert_consecutive(counts(sim, np.concatenate(got[:3])))
    finally:
        sim.close()


@pytest.mark.parametrize(("script", "code", "function"), [
    (lambda t: t.co_channels.add_co_pulse_chan_freq("Dev1/ctr0"), -200430,
     "DAQmxCreateCOPulseChanFreq"),
    (lambda t: t.ci_channels.add_ci_freq_chan("Dev1/ctr0"), -200431, "DAQmxCreateCIFreqChan"),
    (lambda t: t.ai_channels.add_ai_thrmcpl_chan("Dev1/ai0"), -200431,
     "DAQmxCreateAIThrmcplChan"),
])
def test_what_the_6001_lacks_answers_nis_code_naming_the_call(sim: Served, script: object,
                                                              code: int, function: str) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            script(task)  # type: ignore[operator]
        assert info.value.error_code == code
        assert function in str(info.value)


def test_an_unknown_property_names_itself(sim: Served) -> None:
    with nidaqmx.Task(grpc_options=sim.options) as task:
        task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            _ = task.timing.ai_conv_rate
        assert info.value.error_code == -200197
        assert "Timing.ai_conv_rate" in str(info.value)
        assert "does not support DAQmxGetTimingAttributeDouble" in str(info.value)


def test_no_rpc_of_the_service_is_left_unimplemented() -> None:
    from nidaqmx._stubs import nidaqmx_pb2 as pb
    from nidaqmx._stubs import nidaqmx_pb2_grpc as pb_grpc

    methods = [m.name for m in pb.DESCRIPTOR.services_by_name["NiDAQmx"].methods]
    left = [m for m in methods
            if getattr(Usb6001Servicer, m) is getattr(pb_grpc.NiDAQmxServicer, m)]
    assert left == []
    assert "ReadAnalogF64" not in NOT_SIMULATED
    assert not {"CreateAOVoltageChan", "CreateDIChan", "CreateDOChan", "CreateCICountEdgesChan",
                "CfgDigEdgeStartTrig", "ReadAnalogWaveforms"} & set(NOT_SIMULATED)


def test_event_stream_ends_when_the_task_is_cleared(sim: Served) -> None:
    """Bounded: closing a task with a registered event returns promptly."""
    task = nidaqmx.Task(grpc_options=sim.options)
    task.ai_channels.add_ai_voltage_chan("Dev1/ai0")
    task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
    task.register_every_n_samples_acquired_into_buffer_event(10, lambda *a: 0)
    start = time.monotonic()
    task.close()
    assert time.monotonic() - start < 5.0


def test_an_nidaqmx_script_reads_the_load_cells_drift_and_correlated_noise() -> None:
    """The noise beyond white that bring-up learns (issue 30) reaches an NI user's own script
    through the wire as the model says: the drift's slope, the Ornstein-Uhlenbeck part's rms
    and correlation time, on the 14-bit lattice."""
    drift, rms, tau = 0.05, 0.02, 0.05  # V/s, V, s
    clock = VirtualClock()
    device = compression_daq(clock, lambda t: -1e-3, 0.0, noise_rms=0.0, noise_drift=drift,
                             noise_correlated=(rms, tau), seed=3)  # the plate far off
    server = start_server(device)
    channel = server.channel()
    try:
        options = nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name="")
        with nidaqmx.Task(grpc_options=options) as task:
            task.ai_channels.add_ai_voltage_chan("Dev1/ai0", min_val=-10.0, max_val=10.0)
            task.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.FINITE,
                                            samps_per_chan=20_000)
            v = np.asarray(task.read(READ_ALL_AVAILABLE, timeout=60.0))
    finally:
        channel.close()
        server.stop()
    assert len(v) == 20_000
    steps = (v - v[0]) / LSB
    assert np.allclose(steps, np.round(steps), atol=1e-6)  # the ADC's codes
    t = np.arange(len(v)) * 1e-3
    slope, _ = np.polyfit(t, v, 1)
    assert slope == pytest.approx(drift, rel=0.1)  # the OU part's slope error: ~2.5 mV/s
    rest = v - np.polyval(np.polyfit(t, v, 1), t)
    assert np.std(rest) == pytest.approx(rms, rel=0.15)
    lag = round(tau / 1e-3)
    assert np.corrcoef(rest[:-lag], rest[lag:])[0, 1] == pytest.approx(np.exp(-1.0), abs=0.1)
