"""The simulated USB-6001 without the wire: ADC, sample clock, buffer, limits, signals."""

from __future__ import annotations

import numpy as np
import pytest

from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics.contact import Material, hertz_prefactor
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.simulators.usb6001.device import (
    CONTINUOUS,
    DIFF,
    FINITE,
    RSE,
    VOLTS,
    DaqmxError,
    DeviceSpec,
    SimulatedUsb6001,
    default_buffer_size,
)
from gelrig.simulators.usb6001.signals import ConstantSignal, LoadCellSignal, SampleCounterSignal

LSB = DeviceSpec().lsb


def make_task(dev: SimulatedUsb6001, rate: float = 1000.0, chans: str = "Dev1/ai0",
              terminal: int = RSE, mode: int = CONTINUOUS, samps: int = 1000) -> str:
    name = dev.create_task("")
    dev.add_voltage_channel(name, chans, "", terminal, -10.0, 10.0, VOLTS)
    dev.cfg_timing(name, rate, mode, samps)
    return name


def test_adc_quantizes_to_14_bits_and_clips_near_10_5_volts() -> None:
    clock = VirtualClock()
    levels = {"ai0": ConstantSignal(0.123456), "ai1": ConstantSignal(12.0),
              "ai2": ConstantSignal(-30.0)}
    dev = SimulatedUsb6001(clock, levels)
    task = make_task(dev, chans="Dev1/ai0:2")
    dev.start(task)
    data, got = dev.read(task, 10, 1.0)
    assert got == 10 and data.shape == (3, 10)
    assert pytest.approx(20.0 / 16384) == LSB
    assert data[0] == pytest.approx(np.round(0.123456 / LSB) * LSB)
    assert abs(data[0, 0] - 0.123456) <= LSB / 2
    assert data[1] == pytest.approx(10.5, abs=LSB)
    assert data[2] == pytest.approx(-10.5, abs=LSB)


def test_read_advances_virtual_time_to_the_last_sample() -> None:
    clock = VirtualClock(5.0)
    counter = SampleCounterSignal(LSB)
    dev = SimulatedUsb6001(clock, {"ai0": counter})
    task = make_task(dev, rate=100.0)
    dev.start(task)
    data, _ = dev.read(task, 250, 10.0)
    assert clock.now() == pytest.approx(5.0 + 249 / 100.0)
    data2, _ = dev.read(task, 250, 10.0)
    k = counter.decode(np.concatenate([data[0], data2[0]]))
    assert np.all(np.diff(k) == 1)


def test_overflow_when_reads_fall_behind_and_it_sticks_until_restart() -> None:
    clock = VirtualClock()
    dev = SimulatedUsb6001(clock)
    task = make_task(dev, rate=100.0)  # buffer: DAQmx's 1 kS at <= 100 S/s
    dev.start(task)
    dev.read(task, 100, 10.0)
    clock.advance(9.9)  # 990 unread: still fits
    dev.read(task, 10, 10.0)
    clock.advance(10.1)
    with pytest.raises(DaqmxError) as info:
        dev.read(task, 10, 10.0)
    assert info.value.code == -200279
    with pytest.raises(DaqmxError):
        dev.read(task, 1, 10.0)
    dev.stop(task)
    dev.start(task)
    assert dev.read(task, 5, 10.0)[1] == 5


def test_a_waiting_read_drains_the_buffer_so_it_may_be_longer() -> None:
    clock = VirtualClock()
    counter = SampleCounterSignal(LSB)
    dev = SimulatedUsb6001(clock, {"ai0": counter}, buffer_size=100)
    task = make_task(dev, rate=1000.0)
    dev.start(task)
    data, got = dev.read(task, 1000, 10.0)
    assert got == 1000
    assert np.all(np.diff(counter.decode(data[0])) == 1)


def test_buffer_override_and_default_rule() -> None:
    assert [default_buffer_size(r) for r in (100, 1000, 20000)] == [1000, 10_000, 100_000]
    clock = VirtualClock()
    dev = SimulatedUsb6001(clock, buffer_size=50)
    task = make_task(dev, rate=1000.0)
    dev.start(task)
    clock.advance(0.06)
    with pytest.raises(DaqmxError, match="-200279"):
        dev.read(task, 1, 1.0)


def test_timeout_returns_the_samples_that_arrived() -> None:
    clock = VirtualClock()
    dev = SimulatedUsb6001(clock)
    task = make_task(dev, rate=1000.0)
    dev.start(task)
    with pytest.raises(DaqmxError) as info:
        dev.read(task, 5000, 2.0)
    assert info.value.code == -200284
    assert info.value.samps_read == 2001
    assert info.value.data is not None and info.value.data.shape == (1, 2001)
    assert clock.now() == pytest.approx(2.0)


def test_finite_acquisition_ends() -> None:
    dev = SimulatedUsb6001(VirtualClock())
    task = make_task(dev, rate=1000.0, mode=FINITE, samps=100)
    dev.start(task)
    assert dev.read(task, -1, 10.0)[1] == 100
    with pytest.raises(DaqmxError, match="-200278"):
        dev.read(task, 1, 10.0)


def test_aggregate_rate_limit_is_shared_by_the_channels() -> None:
    dev = SimulatedUsb6001(VirtualClock())
    task = make_task(dev, rate=15_000.0, chans="Dev1/ai0:1")
    assert dev.max_rate(task) == pytest.approx(10_000.0)
    with pytest.raises(DaqmxError, match="-200077"):
        dev.start(task)
    with pytest.raises(DaqmxError, match="-200077"):
        dev.cfg_timing(task, 25_000.0, CONTINUOUS, 1000)


@pytest.mark.parametrize(
    ("chans", "terminal", "code"),
    [("Dev2/ai0", RSE, -200220), ("Dev1/ai8", RSE, -200170), ("Dev1/ai4", DIFF, -200170),
     ("Dev1/ao0", RSE, -200170)],
)
def test_channel_errors(chans: str, terminal: int, code: int) -> None:
    dev = SimulatedUsb6001(VirtualClock())
    task = dev.create_task("t")
    with pytest.raises(DaqmxError) as info:
        dev.add_voltage_channel(task, chans, "", terminal, -10.0, 10.0, VOLTS)
    assert info.value.code == code


def test_range_is_plus_minus_ten_volts_only() -> None:
    dev = SimulatedUsb6001(VirtualClock())
    task = dev.create_task("t")
    with pytest.raises(DaqmxError, match="-200077"):
        dev.add_voltage_channel(task, "Dev1/ai0", "", RSE, -20.0, 20.0, VOLTS)
    with pytest.raises(DaqmxError, match="-200082"):
        dev.add_voltage_channel(task, "Dev1/ai0", "", RSE, 1.0, -1.0, VOLTS)


def test_one_analog_input_task_runs_at_a_time() -> None:
    dev = SimulatedUsb6001(VirtualClock())
    a, b = make_task(dev), make_task(dev)
    dev.start(a)
    with pytest.raises(DaqmxError, match="-50103"):
        dev.start(b)
    dev.stop(a)
    dev.start(b)


def test_load_cell_signal_goes_through_the_chain() -> None:
    elastic = Material(5000.0)
    contact = PlateSphereContact(elastic, 9.3e-3, 0.0, lambda t: 1e-3)
    chain = LoadCellChain(offset=0.02, bandwidth=1e5)
    signal = LoadCellSignal(contact, chain, noise_rms=0.0)
    force = hertz_prefactor(9.3e-3) * 5000.0 * 1e-3**1.5
    assert signal.volts(0.0, 1e-3, 5) == pytest.approx(0.02 + 4.0 * force)


def test_noise_is_seeded() -> None:
    def record(seed: int) -> np.ndarray:
        contact = PlateSphereContact(Material(5000.0), 9.3e-3, 0.0, lambda t: -1e-3)
        return LoadCellSignal(contact, LoadCellChain(), 1e-3, seed).volts(0.0, 0.01, 1000)

    assert np.array_equal(record(3), record(3))
    assert not np.array_equal(record(3), record(4))
    assert np.std(record(3)) == pytest.approx(1e-3, rel=0.1)


def test_conditioner_bandwidth_is_one_pole() -> None:
    contact = PlateSphereContact(Material(5000.0), 9.3e-3, 0.0,
                                 lambda t: 1e-3 if t >= 0.0105 else -1e-3)
    chain = LoadCellChain(bandwidth=100.0)
    v = LoadCellSignal(contact, chain, noise_rms=0.0).volts(0.0, 1e-4, 2000)
    final = v[-1]
    step = np.argmax(v > 0)
    # Held input, one pole at 100 Hz: 1 - exp(-2 pi f t) of the step after t (k + 1 samples).
    k = np.arange(40)
    expected = 1 - np.exp(-2 * np.pi * 100.0 * 1e-4 * (k + 1))
    assert v[step + k] / final == pytest.approx(expected, rel=1e-9)
    assert expected[15] == pytest.approx(0.63, abs=0.01)
