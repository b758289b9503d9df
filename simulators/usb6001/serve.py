"""Simulated NI USB-6001 (load-cell input) served as an NI gRPC Device Server.

``gelrig sim serve usb6001 --port 31763 --clock paced:10`` serves Dev1 until interrupted; the
official nidaqmx client connects with ``GrpcSessionOptions(grpc_channel=..., session_name="")``
and the gelrig driver with the address ``grpc://HOST:PORT``. Standing alone, the plate follows
a ramp-and-hold of its own (``--ramp-speed``; 0 keeps it still); in a composed rig the stage
simulator supplies the plate position instead.
"""

from __future__ import annotations

import argparse
import sys
import threading

from instrument.clock import clock_from_spec
from instrument.errors import ConfigError
from instrument.loadcell import LoadCellChain
from instrument.paper import DEPTH_HOLD
from instrument.units import to_si
from simulators.serve_options import USB6001_PORT as DEFAULT_PORT
from simulators.serve_options import usb6001_arguments as add_arguments
from simulators.usb6001.rig import SIM_OFFSET, compression_daq
from simulators.usb6001.server import start_server
from simulators.usb6001.signals import DEFAULT_NOISE_RMS

__all__ = ["DEFAULT_PORT", "add_arguments", "run"]


def _or_default(text: str | None, default: float, unit: str, field: str) -> float:
    """An option's value in SI; ``default`` when it was not given."""
    return default if text is None else to_si(text, unit, field)


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Serve until interrupted (or ``stop`` is set); print where it listens."""
    clock = clock_from_spec(args.clock)
    first_touch = to_si(args.first_touch, "m", "--first-touch")
    start = to_si(args.plate_start, "m", "--plate-start")
    speed = to_si(args.ramp_speed, "m/s", "--ramp-speed")
    depth = _or_default(args.depth, DEPTH_HOLD, "m", "--depth")
    noise = _or_default(args.noise, DEFAULT_NOISE_RMS, "V", "--noise")
    offset = _or_default(args.offset, SIM_OFFSET, "V", "--offset")
    if speed < 0:
        raise ConfigError("--ramp-speed", args.ramp_speed, "must be >= 0 m/s")
    if not 0 <= args.port <= 65535:
        raise ConfigError("--port", args.port, "allowed [0, 65535]")
    t0 = clock.now()
    end = first_touch + depth

    def plate(t: float) -> float:
        return start if speed == 0 else min(start + speed * (t - t0), max(end, start))

    device = compression_daq(
        clock, plate, first_touch, chain=LoadCellChain(offset=offset),
        noise_rms=noise, seed=args.seed, buffer_size=args.buffer_size,
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
