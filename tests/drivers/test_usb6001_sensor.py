"""HIL: the USB-6001 force driver, through the official nidaqmx client and real gRPC, against
the simulated USB-6001 fed by the plate-on-sphere physics."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import grpc
import nidaqmx
import numpy as np
import pytest

from gelrig.drivers.usb6001 import (
    DaqDeviceNotFoundError,
    DaqDriverNotFoundError,
    Usb6001Config,
    Usb6001ForceSensor,
)
from gelrig.instrument.analysis.relaxation import fit_relaxation, modulus_history
from gelrig.instrument.contracts.loadcell import (
    AcquisitionOverflowError,
    ForceOverRangeError,
    ForceSensor,
    LoadCellChain,
)
from gelrig.instrument.core.clock import Clock, PacedClock, VirtualClock
from gelrig.instrument.core.errors import ConfigError, Disconnected, InstrumentError
from gelrig.instrument.physics.contact import Material, hertz_prefactor
from gelrig.simulators.usb6001 import RunningServer, SimulatedUsb6001, compression_daq, start_server
from gelrig.simulators.usb6001.rig import SIM_OFFSET

DIAMETER = 18.63e-3
RADIUS = DIAMETER / 2
DEPTH = 0.06 * DIAMETER
SPEED = 0.002 * DIAMETER
TOUCH = 4.0e-3  # stage position of the sphere's top (what a contact search would find)
APPROACH = 0.2e-3  # the plate starts this far above the sphere
T_MOVE = 5.0  # s: the plate starts moving
T_HOLD = T_MOVE + (APPROACH + DEPTH) / SPEED
HOLD = 3000.0
PLATES = Material.of(7146.0, [(630.0, 1413.0)])


def plate(t: np.ndarray) -> np.ndarray:
    """Ramp 6 % into the sphere at a strain rate of 0.002 /s, then hold (vectorised)."""
    return np.minimum(TOUCH - APPROACH + SPEED * np.maximum(t - T_MOVE, 0.0), TOUCH + DEPTH)


class Served:
    """A simulated device behind a gRPC server and one client channel."""

    def __init__(self, device: SimulatedUsb6001):
        self.device = device
        self.server: RunningServer = start_server(device)
        self.channel = self.server.channel()
        self.options = nidaqmx.GrpcSessionOptions(grpc_channel=self.channel, session_name="")

    def sensor(self, config: Usb6001Config | None = None,
               chain: LoadCellChain | None = None) -> Usb6001ForceSensor:
        return Usb6001ForceSensor(self.options, config or Usb6001Config(),
                                  chain or LoadCellChain(), self.device.clock).open()

    def close(self) -> None:
        self.channel.close()
        self.server.stop()


@pytest.fixture
def serve() -> Iterator[Callable[[SimulatedUsb6001], Served]]:
    opened: list[Served] = []

    def make(device: SimulatedUsb6001) -> Served:
        opened.append(Served(device))
        return opened[-1]

    yield make
    for s in opened:
        s.close()


def still_plate(clock: Clock, overlap: float, material: Material = PLATES, **kw: object
                ) -> SimulatedUsb6001:
    return compression_daq(clock, lambda t: TOUCH + overlap, TOUCH, material=material,
                           **kw)  # type: ignore[arg-type]


def test_meets_the_force_sensor_contract(serve: Callable[..., Served]) -> None:
    with serve(still_plate(VirtualClock(), -1e-3)).sensor() as sensor:
        assert isinstance(sensor, ForceSensor)
        ident = sensor.identify()
        assert (ident.vendor, ident.model) == ("NI", "USB-6001")
        assert ident.extra["instrument"] == "NI USB-6001"
        assert ident.extra["channel"] == "Dev1/ai0"
        assert ident.extra["transport"] == "grpc"


def test_converts_to_newtons_and_tares(serve: Callable[..., Served]) -> None:
    """Untared, the conditioner offset reads as force; after a tare, zero; then Hertz."""
    clock = VirtualClock()
    overlap = {"value": -0.5e-3}
    elastic = Material(5000.0)
    device = compression_daq(clock, lambda t: TOUCH + overlap["value"], TOUCH,
                             material=elastic)
    with serve(device).sensor() as sensor:
        sensor.start(1000.0)
        before = sensor.read_block(2000)
        assert np.mean(before.force) == pytest.approx(SIM_OFFSET / 4.0, abs=2e-5)
        removed = sensor.tare(2.0)
        assert removed == pytest.approx(SIM_OFFSET / 4.0, abs=2e-5)
        assert np.mean(sensor.read_block(2000).force) == pytest.approx(0.0, abs=2e-5)
        overlap["value"] = 0.8e-3
        pressed = sensor.read_block(5000)
        expected = hertz_prefactor(RADIUS) * 5000.0 * 0.8e-3**1.5
        assert np.mean(pressed.force[10:]) == pytest.approx(expected, abs=3e-5)
        assert not pressed.any_over_range


def test_blocks_are_contiguous_on_the_sample_clock(serve: Callable[..., Served]) -> None:
    clock = VirtualClock(100.0)
    with serve(still_plate(clock, -1e-3)).sensor() as sensor:
        sensor.start(100.0)
        blocks = [sensor.read_block(n) for n in (1, 99, 250, 1000)]
        t = np.concatenate([b.t for b in blocks])
        assert t[0] == pytest.approx(100.0)
        assert np.diff(t) == pytest.approx(np.full(t.size - 1, 0.01))
        assert clock.now() == pytest.approx(t[-1])
        clock.advance(0.5)
        assert len(sensor.read_block()) == 50  # all available


def test_compression_in_virtual_time_recovers_the_material(serve: Callable[..., Served]) -> None:
    """Ramp 6 % at 0.002 /s, hold 3000 s, record at 100 Hz; the hold fit gives G_e and tau."""
    clock = VirtualClock()
    device = compression_daq(clock, plate, TOUCH, vectorized=True, material=PLATES,
                             sphere_radius=RADIUS)
    wall = time.perf_counter()
    with serve(device).sensor() as sensor:
        sensor.start(100.0)
        sensor.tare(1.0)  # the plate is still 0.2 mm above the sphere
        ts, fs = [], []
        while clock.now() < T_HOLD + HOLD:
            block = sensor.read_block(2000)
            ts.append(block.t)
            fs.append(block.force)
    wall = time.perf_counter() - wall
    t, f = np.concatenate(ts), np.concatenate(fs)
    assert np.all(np.diff(t) == pytest.approx(0.01))
    hold = t >= T_HOLD
    g = modulus_history(f[hold], DEPTH, RADIUS)
    fit = fit_relaxation(t[hold] - T_HOLD, g)
    assert fit.g_e == pytest.approx(PLATES.g_e, rel=0.02)
    assert fit.relax[0].tau == pytest.approx(PLATES.relax[0].tau, rel=0.02)
    assert wall < 10.0  # 303 000 samples through gRPC in virtual time


def test_overflow_when_reads_fall_behind_in_paced_time(serve: Callable[..., Served]) -> None:
    clock = PacedClock(200.0)
    with serve(still_plate(clock, -1e-3)).sensor() as sensor:
        sensor.start(1000.0)  # buffer 10 kS = 10 s of virtual time = 50 ms of wall time
        for _ in range(5):  # keeping up: fine
            assert len(sensor.read_block(200)) == 200
        time.sleep(0.08)  # 16 s of virtual time unread
        with pytest.raises(AcquisitionOverflowError) as info:
            sensor.read_block(200)
        assert info.value.code == -200279
        assert "fell behind" in str(info.value)


def test_over_range_is_raised_with_the_flagged_block(serve: Callable[..., Served]) -> None:
    # A conditioner gain 40x too high for this load: the hold force drives the input past 10.5 V.
    chain = LoadCellChain(gain=40_000.0)
    device = still_plate(VirtualClock(), DEPTH, chain=chain)
    with serve(device).sensor() as sensor:
        sensor.start(100.0)
        with pytest.raises(ForceOverRangeError) as info:
            sensor.read_block(100)
        block = info.value.block
        assert block.over_range.all()
        assert block.volts == pytest.approx(np.full(100, 10.5), abs=2e-3)  # clipped
        assert "beyond +-10 V" in str(info.value)


def test_over_range_can_be_flagged_instead(serve: Callable[..., Served]) -> None:
    device = compression_daq(VirtualClock(), lambda t: TOUCH + (DEPTH if t > 0.5 else -1e-3),
                             TOUCH, chain=LoadCellChain(gain=40_000.0))
    served = serve(device)
    with served.sensor(Usb6001Config(on_over_range="flag")) as sensor:
        sensor.start(100.0)
        block = sensor.read_block(100)
        assert not block.over_range[:50].any()
        assert block.over_range[51:].all()


def test_missing_nidaqmx_driver_gives_a_clear_message() -> None:
    """Without NI-DAQmx (as on this machine) the local path names the two ways out."""
    try:
        sensor = Usb6001ForceSensor("local", Usb6001Config(), LoadCellChain(),
                                    VirtualClock()).open()
    except DaqDriverNotFoundError as exc:
        text = str(exc)
        assert "NI-DAQmx" in text and "Install" in text
        assert "gelrig sim serve usb6001" in text
        assert isinstance(exc.__cause__, nidaqmx.errors.DaqNotFoundError)
        assert not isinstance(exc.__cause__, nidaqmx.errors.DaqError)
    else:  # pragma: no cover - only where the NI driver is installed
        sensor.close()
        pytest.skip("NI-DAQmx is installed here: the driver-missing path cannot be reached")


def test_missing_device_on_the_server(serve: Callable[..., Served]) -> None:
    served = serve(still_plate(VirtualClock(), -1e-3))
    with pytest.raises(DaqDeviceNotFoundError, match="Dev3"):
        served.sensor(Usb6001Config(device="Dev3"))
    assert served.device._tasks == {}  # the half-made task was cleared


def test_unreachable_server_is_a_disconnection() -> None:
    with grpc.insecure_channel("127.0.0.1:1") as channel, pytest.raises(Disconnected):
        Usb6001ForceSensor(nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name=""),
                           Usb6001Config(), LoadCellChain(), VirtualClock()).open()


def test_open_by_address_owns_and_closes_its_channel(serve: Callable[..., Served]) -> None:
    served = serve(still_plate(VirtualClock(), -1e-3))
    sensor = Usb6001ForceSensor(f"grpc://{served.server.address}", Usb6001Config(),
                                LoadCellChain(), served.device.clock).open()
    sensor.start(200.0)
    assert len(sensor.read_block(10)) == 10
    sensor.close()
    assert served.device._tasks == {}
    with pytest.raises(InstrumentError, match="closed"):
        sensor.start(200.0)
    with pytest.raises(ConfigError, match="address"):
        Usb6001ForceSensor("tcp-somewhere", Usb6001Config(), LoadCellChain(), VirtualClock())


@pytest.mark.parametrize("rate", [50.0, 20_001.0])
def test_rate_outside_100_hz_to_the_device_limit(serve: Callable[..., Served],
                                                 rate: float) -> None:
    with serve(still_plate(VirtualClock(), -1e-3)).sensor() as sensor:
        assert sensor.max_rate() == pytest.approx(20_000.0)
        with pytest.raises(ConfigError, match=r"\[100, 20000\] Hz"):
            sensor.start(rate)


def test_read_and_tare_need_a_running_acquisition(serve: Callable[..., Served]) -> None:
    with serve(still_plate(VirtualClock(), -1e-3)).sensor() as sensor:
        with pytest.raises(InstrumentError, match="before start"):
            sensor.read_block(10)
        with pytest.raises(InstrumentError, match="before start"):
            sensor.tare()


def test_differential_wiring_is_passed_to_the_device(serve: Callable[..., Served]) -> None:
    served = serve(still_plate(VirtualClock(), -1e-3))
    with served.sensor(Usb6001Config(terminal="DIFF", channel="ai0")) as sensor:
        term = sensor.task.ai_channels[0].ai_term_cfg
        assert term == nidaqmx.constants.TerminalConfiguration.DIFF


@pytest.mark.parametrize(
    ("mapping", "field"),
    [({"terminal": "NRSE"}, "[force] terminal"),
     ({"channel": "ai5", "terminal": "diff"}, "[force] channel"),
     ({"buffer_seconds": "2 h"}, "[force] buffer_seconds"), ({"over_range_volts": "11 V"},
                                                     "[force] over_range_volts"),
     ({"device": 3}, "[force] device"), ({"speed": 1}, "[force] speed")],
)
def test_config_from_table_names_the_field(mapping: dict[str, object], field: str) -> None:
    with pytest.raises(ConfigError) as info:
        Usb6001Config.from_table(mapping, "rig.toml")
    assert info.value.field == field
    assert info.value.source == "rig.toml"


def test_config_from_table_accepts_units() -> None:
    config = Usb6001Config.from_table(
        {"device": "Dev2", "channel": "ai3", "terminal": "diff", "buffer_seconds": "1 min"})
    assert (config.physical_channel, config.terminal, config.buffer_seconds) == (
        "Dev2/ai3", "DIFF", 60.0)


# ---- lifecycle (ADR 0050) -----------------------------------------------------------------
def test_constructing_does_no_io(serve: Callable[..., Served]) -> None:
    sensor = Usb6001ForceSensor("grpc://127.0.0.1:1", Usb6001Config(), LoadCellChain(),
                                VirtualClock())  # nobody listens there
    assert not sensor.is_open
    with pytest.raises(Disconnected):
        sensor.open()
    assert not sensor.is_open
    sensor.close()
    served = serve(still_plate(VirtualClock(), -1e-3))
    sensor = Usb6001ForceSensor(served.options, Usb6001Config(), LoadCellChain(),
                                served.device.clock)
    assert served.device._tasks == {}
    with sensor:
        assert len(served.device._tasks) == 1
        assert sensor.identify().model == "USB-6001"
    assert served.device._tasks == {}
    sensor.close()  # idempotent


class _InterruptRead(grpc.UnaryUnaryClientInterceptor):  # type: ignore[misc]
    """Ctrl-C just after a read RPC returned: samples left the server but were never counted."""

    def __init__(self) -> None:
        self.armed = False

    def intercept_unary_unary(self, continuation: Any, details: Any, request: Any) -> Any:
        response = continuation(details, request)
        if self.armed and details.method.endswith("/ReadAnalogF64"):
            self.armed = False
            raise KeyboardInterrupt
        return response


def test_ctrl_c_during_a_read_stops_the_acquisition(serve: Callable[..., Served]) -> None:
    served = serve(still_plate(VirtualClock(), -1e-3))
    interrupt = _InterruptRead()
    channel = grpc.intercept_channel(served.channel, interrupt)
    options = nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name="")
    with Usb6001ForceSensor(options, Usb6001Config(), LoadCellChain(),
                            served.device.clock) as sensor:
        sensor.start(1000.0)
        assert len(sensor.read_block(100)) == 100
        (task,) = served.device._tasks.values()
        assert task.running
        interrupt.armed = True
        with pytest.raises(KeyboardInterrupt):
            sensor.read_block(100)
        assert not task.running  # StopTask reached the device
        with pytest.raises(InstrumentError, match="before start"):
            sensor.read_block(10)  # the next block needs a fresh start(), counted from zero
        t0 = served.device.clock.now()
        sensor.start(1000.0)
        assert sensor.read_block(10).t[0] == pytest.approx(t0)


def test_typed_read_errors_leave_the_acquisition_running(serve: Callable[..., Served]) -> None:
    chain = LoadCellChain(gain=40_000.0)
    served = serve(still_plate(VirtualClock(), DEPTH, chain=chain))
    with served.sensor() as sensor:
        sensor.start(100.0)
        with pytest.raises(ForceOverRangeError):
            sensor.read_block(100)
        (task,) = served.device._tasks.values()
        assert task.running  # every sample is accounted for: the caller may read on
