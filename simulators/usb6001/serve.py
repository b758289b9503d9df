"""Simulated NI USB-6001 (load-cell input) served as an NI gRPC Device Server.

``gelrig sim serve usb6001 --port 31763 --clock paced:10`` serves Dev1 until interrupted; the
official nidaqmx client connects with ``GrpcSessionOptions(grpc_channel=..., session_name="")``
and the gelrig driver with the address ``grpc://HOST:PORT``. Standing alone, the plate follows
a ramp-and-hold of its own (``--ramp-speed``; 0 keeps it still); in a composed rig the stage
simulator supplies the plate position instead.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import threading

from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.clock import clock_from_spec
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.options import config_from_options
from gelrig.simulators.serve_options import USB6001_PORT as DEFAULT_PORT
from gelrig.simulators.serve_options import usb6001_arguments as add_arguments
from gelrig.simulators.usb6001.config import Standalone
from gelrig.simulators.usb6001.device import DOCUMENTED, DaqTiming, DeviceSpec
from gelrig.simulators.usb6001.rig import compression_daq
from gelrig.simulators.usb6001.server import start_server

__all__ = ["DEFAULT_PORT", "add_arguments", "run"]


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Serve until interrupted (or ``stop`` is set); print where it listens."""
    clock = clock_from_spec(args.clock, waits_only=False)
    sample = config_from_options(Standalone, args, "gelrig sim serve usb6001")
    if not 0 <= args.port <= 65535:
        raise ConfigError("--port", args.port, "allowed [0, 65535]")
    t0 = clock.now()
    start, speed = sample.plate_start, sample.ramp_speed
    end = sample.first_touch + sample.depth

    def plate(t: float) -> float:
        return start if speed == 0 else min(start + speed * (t - t0), max(end, start))

    device = compression_daq(
        clock, plate, sample.first_touch, chain=LoadCellChain(offset=sample.offset),
        noise_rms=sample.noise, seed=sample.seed, buffer_size=sample.buffer_size,
        spec=DeviceSpec(timing=dataclasses.replace(DOCUMENTED, seed=sample.seed)
                        if sample.timing == "documented" else DaqTiming()),
    )
    try:
        server = start_server(device, args.host, args.port)
    except (OSError, RuntimeError) as exc:
        raise ConfigError("--port", args.port, f"cannot listen on {args.host}: {exc}") from None
    print(f"usb6001: simulated {device.spec.product_type} {device.spec.name} listening on "
          f"grpc://{server.address} (clock {args.clock})", flush=True)
    try:
        duration = getattr(args, "duration", None)
        if stop is None:
            server.server.wait_for_termination(timeout=duration)
        else:
            stop.wait(duration)
    except KeyboardInterrupt:
        print("usb6001: stopped", file=sys.stderr)
    finally:
        server.stop()
    return 0
