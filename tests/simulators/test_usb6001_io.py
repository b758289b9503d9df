"""The simulated USB-6001 beyond its analog input, as an owner's nidaqmx scripts use it: AO on
demand and clocked (regeneration, non-regeneration, range and rate limits), static DIO with
line states the twin sees, ctr0 edge counting on PFI 0, digital start triggers, waveform
reads, the device properties scripts read, and NI's codes for what the 6001 lacks
(docs/decisions/0290)."""

from __future__ import annotations

import datetime
from collections.abc import Iterator

import nidaqmx
import numpy as np
import pytest
from nidaqmx.constants import (
    AcquisitionType,
    CountDirection,
    Edge,
    LineGrouping,
    RegenerationMode,
    TerminalConfiguration,
    TriggerUsage,
)

from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.usb6001 import ConstantSignal, SimulatedUsb6001, start_server
from gelrig.simulators.usb6001.ao import AoLoopback, ao_lsb
from gelrig.simulators.usb6001.subsystems import Usb6001Io, io_of

AO_LSB = ao_lsb()
RSE = TerminalConfiguration.RSE
EPOCH = datetime.datetime(1970, 1, 1, tzinfo=datetime.UTC)


class Twin:
    """The served simulator with ao0 wired to ai0 and 2.5 V on ai1."""

    def __init__(self) -> None:
        self.clock = VirtualClock()
        self.device = SimulatedUsb6001(self.clock, {
            "ai0": AoLoopback(lambda: io_of(self.device), 0), "ai1": ConstantSignal(2.5)})
        self.io: Usb6001Io = io_of(self.device)
        self.server = start_server(self.device)
        self.channel = self.server.channel()
        self.options = nidaqmx.GrpcSessionOptions(grpc_channel=self.channel, session_name="")

    def task(self) -> nidaqmx.Task:
        return nidaqmx.Task(grpc_options=self.options)

    def close(self) -> None:
        self.channel.close()
        self.server.stop()


@pytest.fixture
def twin() -> Iterator[Twin]:
    t = Twin()
    yield t
    t.close()


def finite_ai(ai: nidaqmx.Task, rate: float, n: int) -> None:
    """ai1 (2.5 V), RSE, +-10 V, a finite acquisition of ``n`` samples at ``rate``."""
    ai.ai_channels.add_ai_voltage_chan("Dev1/ai1", terminal_config=RSE, min_val=-10, max_val=10)
    ai.timing.cfg_samp_clk_timing(rate, sample_mode=AcquisitionType.FINITE, samps_per_chan=n)


def code_of(fn: object) -> int:
    with pytest.raises(nidaqmx.errors.DaqError) as info:
        fn()  # type: ignore[operator]
    return info.value.error_code


# --- analog output ---------------------------------------------------------------------------

def test_on_demand_ao_holds_the_written_value_quantized(twin: Twin) -> None:
    with twin.task() as task:
        task.ao_channels.add_ao_voltage_chan("Dev1/ao0:1", min_val=-10, max_val=10)
        assert task.write([1.1, -3.3]) == 1
        assert abs(twin.io.ao.volts(0) - 1.1) <= AO_LSB / 2
        assert abs(twin.io.ao.volts(1) + 3.3) <= AO_LSB / 2
        assert twin.io.ao.volts(0) != 1.1  # a 14-bit DAC: the code nearest 1.1 V
    assert abs(twin.io.ao.volts(0) - 1.1) <= AO_LSB  # held after the task ends


def test_ao_range_rate_and_data_limits_answer_nis_codes(twin: Twin) -> None:
    with twin.task() as task:
        assert code_of(lambda: task.ao_channels.add_ao_voltage_chan(
            "Dev1/ao0", min_val=-12, max_val=12)) == -200077
        assert code_of(lambda: task.ao_channels.add_ao_voltage_chan("Dev1/ao2")) == -200170
        task.ao_channels.add_ao_voltage_chan("Dev1/ao0", min_val=-5, max_val=5)
        assert code_of(lambda: task.write(7.0)) == -200561  # beyond the channel's max
        assert code_of(lambda: task.timing.cfg_samp_clk_timing(5001)) == -200077
        task.timing.cfg_samp_clk_timing(5000)
        assert task.timing.samp_clk_rate == 5000
        assert code_of(task.start) == -200462  # nothing written: the buffer is empty


def test_finite_generation_is_read_back_through_the_loopback(twin: Twin) -> None:
    ramp = np.linspace(0.0, 5.0, 100, endpoint=False)
    with twin.task() as ao, twin.task() as ai:
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        ao.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.FINITE,
                                      samps_per_chan=100)
        ai.ai_channels.add_ai_voltage_chan("Dev1/ai0", terminal_config=RSE, min_val=-10,
                                           max_val=10)
        ai.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.FINITE,
                                      samps_per_chan=150)
        assert ao.write(ramp) == 100
        assert twin.io.ao.volts(0) == 0.0  # not started: the write did not auto start
        ai.start()
        ao.start()
        ao.wait_until_done()
        got = np.array(ai.read(number_of_samples_per_channel=150))
    assert np.abs(got[:100] - ramp).max() <= 2 * AO_LSB + 2.5e-3  # DAC + ADC quantization
    assert np.all(np.abs(got[100:] - got[99]) < 2.5e-3)  # the DAC holds the last sample


def test_continuous_generation_regenerates_the_buffer(twin: Twin) -> None:
    wave = np.sin(2 * np.pi * np.arange(50) / 50)
    with twin.task() as ao:
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao1")
        ao.timing.cfg_samp_clk_timing(500.0, sample_mode=AcquisitionType.CONTINUOUS)
        ao.write(wave)
        ao.start()
        t0 = twin.clock.now()
        for k in (0, 13, 50 + 13, 5 * 50 + 37):
            assert abs(twin.io.ao.volts(1, t0 + k / 500.0) - wave[k % 50]) <= AO_LSB
        twin.clock.advance(10.0)
        assert not ao.is_task_done()
        assert ao.out_stream.output_onbrd_buf_size > 0
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            ao.wait_until_done(timeout=0.5)
        assert info.value.error_code == -200560
        ao.stop()


def test_non_regenerative_generation_stops_when_it_runs_dry(twin: Twin) -> None:
    with twin.task() as ao:
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        ao.out_stream.regen_mode = RegenerationMode.DONT_ALLOW_REGENERATION
        ao.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS,
                                      samps_per_chan=200)
        ao.write(np.zeros(200))
        ao.start()
        ao.write(np.ones(200))  # waits on the clock for room: the first block must go out
        assert ao.out_stream.total_samp_per_chan_generated >= 1
        twin.clock.advance(1.0)  # nothing more written: 400 samples last 0.4 s
        assert code_of(lambda: ao.write(np.ones(10))) == -200290


# --- digital I/O ---------------------------------------------------------------------------

def test_do_lines_are_seen_by_the_twin_and_read_back_by_di(twin: Twin) -> None:
    with twin.task() as do, twin.task() as di:
        do.do_channels.add_do_chan("Dev1/port1/line0:3", line_grouping=LineGrouping.CHAN_PER_LINE)
        do.write([True, False, True, False])
        assert [twin.io.lines.level(f"port1/line{i}") for i in range(4)] == [
            True, False, True, False]
        di.di_channels.add_di_chan("Dev1/port1", line_grouping=LineGrouping.CHAN_FOR_ALL_LINES)
        assert di.read() == 0b0101
    twin.io.lines.set_input("port2/line0", False)
    with twin.task() as di:
        di.di_channels.add_di_chan("Dev1/port2/line0")
        assert di.read() is False
        di.di_channels.add_di_chan("Dev1/port0/line7")
        assert di.read() == [False, True]  # an undriven line reads high (pull-up)


def test_dio_refusals_are_nis(twin: Twin) -> None:
    with twin.task() as task:
        assert code_of(lambda: task.di_channels.add_di_chan("Dev1/port1/line4")) == -200170
        task.do_channels.add_do_chan("Dev1/port0")
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            task.timing.cfg_samp_clk_timing(1000.0)
        assert info.value.error_code == -200077
        assert "On Demand" in str(info.value) and "SampTimingType" in str(info.value)
        assert code_of(lambda: task.ai_channels.add_ai_voltage_chan("Dev1/ai0")) == -200559
    with twin.task() as task:
        task.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        assert code_of(lambda: task.do_channels.add_do_chan("Dev1/port0")) == -200559


# --- counter -------------------------------------------------------------------------------

def test_ctr0_counts_edges_on_pfi0_from_its_initial_count(twin: Twin) -> None:
    twin.io.lines.square_wave("PFI0", 2000.0, start=twin.clock.now() + 0.0001)
    with twin.task() as task:
        chan = task.ci_channels.add_ci_count_edges_chan(
            "Dev1/ctr0", edge=Edge.FALLING, initial_count=100)
        assert chan.ci_count_edges_term == "/Dev1/PFI0"
        task.start()
        assert task.read() == 100
        twin.clock.advance(0.5)
        assert task.read() == 100 + 1000
        assert chan.ci_count == 1100
        task.stop()
    with twin.task() as task:
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            task.ci_channels.add_ci_count_edges_chan(
                "Dev1/ctr0", count_direction=CountDirection.COUNT_DOWN)
        assert info.value.error_code == -200077
        chan = task.ci_channels.add_ci_count_edges_chan("Dev1/ctr0")
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            chan.ci_count_edges_term = "/Dev1/PFI8"
        assert info.value.error_code == -89120
    with twin.task() as task:
        assert code_of(lambda: task.ci_channels.add_ci_count_edges_chan("Dev1/ctr1")) == -200170
        assert code_of(lambda: task.co_channels.add_co_pulse_chan_freq("Dev1/ctr0")) == -200430


def test_ctr0_counts_edges_a_do_line_makes_on_a_looped_wire(twin: Twin) -> None:
    twin.io.lines.wire("port0/line0", "PFI0")
    with twin.task() as ci, twin.task() as do:
        ci.ci_channels.add_ci_count_edges_chan("Dev1/ctr0")
        do.do_channels.add_do_chan("Dev1/port0/line0")
        do.write(False)
        ci.start()
        for _ in range(7):
            twin.clock.advance(0.001)
            do.write(True)
            twin.clock.advance(0.001)
            do.write(False)
        assert ci.read() == 7


# --- triggers --------------------------------------------------------------------------------

def test_ai_waits_for_its_digital_start_trigger(twin: Twin) -> None:
    with twin.task() as ai:
        finite_ai(ai, 1000.0, 10)
        ai.triggers.start_trigger.cfg_dig_edge_start_trig("/Dev1/PFI1", Edge.RISING)
        ai.start()
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            ai.read(number_of_samples_per_channel=10, timeout=0.2)  # no edge: nothing acquired
        assert info.value.error_code == -200284
        edge = twin.clock.now() + 1.0
        twin.io.lines.pulse("PFI1", edge)
        waveform = ai.read_waveform(number_of_samples_per_channel=10) if hasattr(
            ai, "read_waveform") else None
        data = ai.read(number_of_samples_per_channel=10, timeout=5.0) if waveform is None \
            else list(waveform.raw_data)
        assert len(data) == 10 and abs(data[0] - 2.5) < 2e-3
        assert twin.clock.now() >= edge + 9 / 1000.0


def test_ao_start_trigger_from_a_looped_do_line(twin: Twin) -> None:
    twin.io.lines.wire("port0/line1", "PFI0")
    with twin.task() as ao, twin.task() as do:
        do.do_channels.add_do_chan("Dev1/port0/line1")
        do.write(False)
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        ao.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.FINITE,
                                      samps_per_chan=4)
        ao.triggers.start_trigger.cfg_dig_edge_start_trig("/Dev1/PFI0")
        ao.write([1.0, 2.0, 3.0, 4.0])
        ao.start()
        twin.clock.advance(0.5)
        assert twin.io.ao.volts(0) == 0.0 and not ao.is_task_done()
        do.write(True)
        fired = twin.clock.now()
        assert abs(twin.io.ao.volts(0, fired + 0.0025) - 3.0) <= AO_LSB
        ao.wait_until_done(timeout=1.0)


def test_analog_and_reference_triggers_are_refused(twin: Twin) -> None:
    with twin.task() as ai:
        ai.ai_channels.add_ai_voltage_chan("Dev1/ai0")
        ai.timing.cfg_samp_clk_timing(1000.0)
        start = ai.triggers.start_trigger
        assert code_of(lambda: start.cfg_anlg_edge_start_trig("Dev1/ai0")) == -200077
        ref = ai.triggers.reference_trigger
        assert code_of(lambda: ref.cfg_dig_edge_ref_trig("/Dev1/PFI0", 10)) == -200077
        assert code_of(lambda: start.cfg_dig_edge_start_trig("/Dev1/PFI3")) == -89120
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            start.retriggerable = True
        assert info.value.error_code == -200452


# --- reads and properties -------------------------------------------------------------------

def test_waveform_read_carries_its_timing(twin: Twin) -> None:
    from nitypes.waveform import AnalogWaveform

    with twin.task() as ai:
        finite_ai(ai, 500.0, 20)
        twin.clock.advance(3.0)
        wave = ai.read_waveform(number_of_samples_per_channel=20) if hasattr(
            ai, "read_waveform") else None
        if wave is None:
            waveform = AnalogWaveform(20)
            ai.in_stream.read(waveform)  # type: ignore[attr-defined]
            wave = waveform
        assert wave.sample_count == 20
        assert abs(wave.timing.sample_interval.total_seconds() - 1 / 500) < 1e-12
        start = wave.timing.start_time
        seconds = (datetime.datetime(start.year, start.month, start.day, start.hour,
                                     start.minute, start.second, start.microsecond,
                                     tzinfo=datetime.UTC) - EPOCH).total_seconds()
        assert abs(seconds - 3.0) < 1e-5  # the first sample: when the task started
        assert np.all(np.abs(wave.scaled_data - 2.5) < 2e-3)


def test_device_properties_an_owner_reads(twin: Twin) -> None:
    dev = nidaqmx.system.Device("Dev1", grpc_options=twin.options)
    assert dev.ao_voltage_rngs == [-10.0, 10.0]
    assert dev.ao_max_rate == 5000.0 and dev.ai_min_rate > 0
    assert set(dev.ai_samp_modes) == {AcquisitionType.FINITE, AcquisitionType.CONTINUOUS}
    assert dev.ai_trig_usage == [TriggerUsage.START] == dev.ao_trig_usage
    assert dev.dig_trig_supported and not dev.anlg_trig_supported
    assert dev.product_num > 0
    assert dev.ao_physical_chans.channel_names == ["Dev1/ao0", "Dev1/ao1"]
    with twin.task() as ai:
        chan = ai.ai_channels.add_ai_voltage_chan("Dev1/ai0:7")
        assert [c.ai_term_cfg for c in ai.ai_channels] == [TerminalConfiguration.DIFF] * 4 + [
            TerminalConfiguration.RSE] * 4  # NI's default for an 8-channel USB-600x
        chan.ai_max = 5.0
        assert ai.ai_channels["Dev1/ai3"].ai_max == 5.0
        with pytest.raises(nidaqmx.errors.DaqError) as info:
            chan.ai_max = 11.0
        assert info.value.error_code == -200077
        assert ai.in_stream.raw_data_width == 2
        assert len(ai.ai_channels["Dev1/ai0"].ai_dev_scaling_coeff) == 2


def test_reset_device_returns_outputs_to_their_power_on_state(twin: Twin) -> None:
    with twin.task() as ao, twin.task() as do:
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao1")
        ao.write(4.0)
        do.do_channels.add_do_chan("Dev1/port0/line3")
        do.write(False)
        nidaqmx.system.Device("Dev1", grpc_options=twin.options).reset_device()
        assert twin.io.ao.volts(1) == 0.0
        assert twin.io.lines.level("port0/line3") is True


def test_tdms_logging_log_only_refuses_reads_and_writes_what_was_acquired(
        twin: Twin, tmp_path: object) -> None:
    from nidaqmx.constants import LoggingMode, LoggingOperation
    from nptdms import TdmsFile

    path = f"{tmp_path}/log.tdms"
    with twin.task() as ai:
        finite_ai(ai, 1000.0, 25)
        ai.in_stream.configure_logging(path, LoggingMode.LOG, group_name="run",
                                       operation=LoggingOperation.CREATE_OR_REPLACE)
        assert ai.in_stream.logging_mode == LoggingMode.LOG
        ai.start()
        assert code_of(lambda: ai.read(5)) == -201301
        ai.wait_until_done()
    data = TdmsFile.read(path)["run"]["Dev1/ai1"]
    assert len(data) == 25 and np.all(np.abs(data[:] - 2.5) < 2e-3)
    assert data.properties["wf_increment"] == pytest.approx(1e-3)
    with twin.task() as ao:
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        assert code_of(lambda: ao.in_stream.configure_logging(path)) == -201332


def test_ao_starts_with_the_ai_on_the_ai_start_trigger(twin: Twin) -> None:
    with twin.task() as ai, twin.task() as ao:
        finite_ai(ai, 1000.0, 100)
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        ao.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        ao.triggers.start_trigger.cfg_dig_edge_start_trig("/Dev1/ai/StartTrigger")
        assert ao.triggers.start_trigger.dig_edge_src == "/Dev1/ai/StartTrigger"
        ao.write(np.arange(1000) / 1000.0)
        ao.start()
        twin.clock.advance(0.5)
        assert twin.io.ao.volts(0) == 0.0  # the AI has not started
        ai.start()
        t0 = twin.clock.now()
        assert abs(twin.io.ao.volts(0, t0 + 0.0405) - 0.040) <= AO_LSB
        with pytest.raises(nidaqmx.errors.DaqError) as info:  # an AI cannot trigger itself
            ai.triggers.start_trigger.cfg_dig_edge_start_trig("/Dev1/ai/StartTrigger")
        assert info.value.error_code == -89120


def test_a_group_of_lines_is_one_channel_named_as_daqmx_names_it(twin: Twin) -> None:
    with twin.task() as do, twin.task() as di:
        chan = do.do_channels.add_do_chan("Dev1/port0/line0:7")  # one channel for all lines
        assert chan.name == "Dev1/port0/line0..." and chan.do_num_lines == 8
        do.write(0x81)
        di.di_channels.add_di_chan("Dev1/port0/line0:7")
        assert di.read(number_of_samples_per_channel=3) == [0x81] * 3


def test_a_non_regenerative_write_waits_for_room_in_the_buffer_of_its_first_write(
        twin: Twin) -> None:
    with twin.task() as ao:
        ao.ao_channels.add_ao_voltage_chan("Dev1/ao0")
        ao.out_stream.regen_mode = RegenerationMode.DONT_ALLOW_REGENERATION
        ao.timing.cfg_samp_clk_timing(1000.0, sample_mode=AcquisitionType.CONTINUOUS)
        ao.write(np.zeros(100))  # the buffer: 100 samples
        ao.start()
        t0 = twin.clock.now()
        for _ in range(3):
            ao.write(np.full(100, 0.5))  # each waits until 100 more have been generated
        assert twin.clock.now() == pytest.approx(t0 + 0.299, abs=1e-9)
        assert ao.out_stream.output_buf_size == 100
