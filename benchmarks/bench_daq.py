"""USB-6001 acquisition through the official nidaqmx client against the simulated device.

Run: python benchmarks/bench_daq.py [--repeats 5]

Prints
1. sustained samples/s through the official client (nidaqmx Task + stream reader over real
   gRPC, virtual clock, 20 kS/s task, 0.1 s blocks: the rate-limited part is the software),
   its ratio to the 6001's 20 kS/s aggregate, and as a baseline the same reads from the
   device model directly (no gRPC, no client) measured in the same run; every sample is
   checked for loss or repetition with a counter pattern;
2. a real-time check: 3 s at 20 kS/s on a real clock through the client, reading 0.1 s blocks
   (no overflow means the client keeps up with the device);
3. wall time of the virtual-time ramp (6 % at 0.002 /s) + 3000 s hold recorded at 1 kHz through
   the gelrig driver (3.03e6 samples; target < 5 s), with as baseline the contact physics
   alone over the same samples.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import nidaqmx
import numpy as np
from nidaqmx.constants import AcquisitionType, TerminalConfiguration
from nidaqmx.stream_readers import AnalogSingleChannelReader

from gelrig.drivers.usb6001 import Usb6001Config, Usb6001ForceSensor
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.clock import Clock, RealClock, VirtualClock
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.simulators.usb6001 import (
    DeviceSpec,
    SampleCounterSignal,
    SimulatedUsb6001,
    compression_daq,
    start_server,
)

AGGREGATE = 20_000.0
BLOCK = 2_000  # 0.1 s at 20 kS/s
TOUCH = 4e-3
APPROACH = 0.2e-3
T_MOVE = 1.0
T_HOLD = T_MOVE + (APPROACH + paper.DEPTH_HOLD) / paper.RAMP_SPEED
T_END = T_HOLD + paper.HOLD


def median_rate(fn: Callable[[], int], repeats: int) -> float:
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        n = fn()
        rates.append(n / (time.perf_counter() - t0))
    return statistics.median(rates)


def counter_device(clock: Clock) -> tuple[SimulatedUsb6001, SampleCounterSignal]:
    counter = SampleCounterSignal(DeviceSpec().lsb)
    return SimulatedUsb6001(clock, {"ai0": counter}), counter


def check(counter: SampleCounterSignal, values: list[np.ndarray]) -> None:
    steps = np.mod(np.diff(counter.decode(np.concatenate(values))), counter.period)
    if not np.all(steps == 1):
        raise SystemExit("FAIL: lost or repeated samples")


def client_run(total: int, clock: Clock | None = None, rate: float = AGGREGATE) -> int:
    """Read ``total`` samples through the official client; return how many were read."""
    device, counter = counter_device(clock or VirtualClock())
    with start_server(device) as server:
        channel = server.channel()
        options = nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name="")
        with nidaqmx.Task(grpc_options=options) as task:
            task.ai_channels.add_ai_voltage_chan(
                "Dev1/ai0", terminal_config=TerminalConfiguration.RSE, min_val=-10.0,
                max_val=10.0)
            task.timing.cfg_samp_clk_timing(rate, sample_mode=AcquisitionType.CONTINUOUS,
                                            samps_per_chan=int(rate))
            reader = AnalogSingleChannelReader(task.in_stream)
            task.start()
            out = []
            for _ in range(total // BLOCK):
                buf = np.empty(BLOCK)
                reader.read_many_sample(buf, BLOCK, timeout=10.0)
                out.append(buf)
        channel.close()
    check(counter, out)
    return len(out) * BLOCK


def direct_run(total: int) -> int:
    """The same reads from the device model, no gRPC and no client."""
    device, counter = counter_device(VirtualClock())
    task = device.create_task("")
    device.add_voltage_channel(task, "Dev1/ai0", "", 10083, -10.0, 10.0, 10348)
    device.cfg_timing(task, AGGREGATE, 10123, int(AGGREGATE))
    device.start(task)
    out = [device.read(task, BLOCK, 10.0)[0][0] for _ in range(total // BLOCK)]
    check(counter, out)
    return len(out) * BLOCK


def plate(t: np.ndarray) -> np.ndarray:
    return np.minimum(TOUCH - APPROACH + paper.RAMP_SPEED * np.maximum(t - T_MOVE, 0.0),
                      TOUCH + paper.DEPTH_HOLD)


def compression_run(rate: float = 1000.0, block_s: float = 10.0) -> tuple[float, int]:
    """Wall time (s) and sample count of the ramp + hold recorded by the driver."""
    clock = VirtualClock()
    device = compression_daq(clock, plate, TOUCH, vectorized=True)
    t0 = time.perf_counter()
    n = 0
    with start_server(device) as server:
        channel = server.channel()
        options = nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name="")
        with Usb6001ForceSensor(options, Usb6001Config(), LoadCellChain(), clock) as sensor:
            sensor.start(rate)
            sensor.tare(1.0)
            while clock.now() < T_END:
                n += len(sensor.read_block(int(rate * block_s)))
        channel.close()
    return time.perf_counter() - t0, n


def physics_run(rate: float = 1000.0) -> float:
    n = int(T_END * rate) + 1
    contact = PlateSphereContact(paper.PLATES, paper.R_COMPRESSION, TOUCH, plate, vectorized=True)
    t0 = time.perf_counter()
    contact.force_on_grid(0.0, 1.0 / rate, n)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--samples", type=int, default=1_000_000,
                        help="samples per throughput run")
    args = parser.parse_args()

    client = median_rate(lambda: client_run(args.samples), args.repeats)
    direct = median_rate(lambda: direct_run(args.samples), args.repeats)
    print(f"sustained through the official nidaqmx client: {client:,.0f} samples/s "
          f"= {client / AGGREGATE:.1f} x the USB-6001's 20 kS/s "
          f"(median of {args.repeats} x {args.samples:,} samples, {BLOCK}-sample reads)")
    print(f"  baseline, device model without gRPC/client: {direct:,.0f} samples/s "
          f"(client path = {client / direct:.2f} of it)")

    t0 = time.perf_counter()
    n = client_run(int(3 * AGGREGATE), RealClock())
    wall = time.perf_counter() - t0
    print(f"real time, 20 kS/s on a real clock: {n:,} samples in {wall:.2f} s, none lost, "
          "no overflow")

    walls = []
    for _ in range(args.repeats):
        wall, n = compression_run()
        walls.append(wall)
    physics = statistics.median(physics_run() for _ in range(args.repeats))
    print(f"virtual-time ramp + 3000 s hold at 1 kHz through the driver: "
          f"{statistics.median(walls):.2f} s wall for {n:,} samples (target < 5 s)")
    print(f"  baseline, contact physics alone over the same samples: {physics:.2f} s")


if __name__ == "__main__":
    main()
