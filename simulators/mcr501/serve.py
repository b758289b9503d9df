"""Serve a simulated MCR 501 rheometer (two hydrogel spheres on the shear arm) over TCP.

``gelrig sim serve mcr501 --port 5025 --clock paced:10`` prints where it listens; connect with
pyvisa as ``TCPIP0::HOST::PORT::SOCKET`` (read termination CR LF; requests may end in CR, LF or
CR LF; one client at a time, docs/decisions/0110). The clock is real
or paced (virtual time at K x real time); a purely virtual clock needs a client in the same
process, so it is not offered here.
"""

from __future__ import annotations

import argparse
import time

from gelrig.instrument.core.clock import Clock, RealClock, VirtualClock, clock_from_spec
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.options import config_from_options
from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.mcr501.instrument import MCR501Simulator
from gelrig.simulators.mcr501.server import SimulatorServer
from gelrig.simulators.serve_options import MCR501_OPTIONS
from gelrig.simulators.serve_options import mcr501_arguments as add_arguments

__all__ = ["add_arguments", "build", "run"]


def build(args: argparse.Namespace) -> tuple[Clock, MCR501Simulator]:
    """The clock and simulator described by the command line (ConfigError on bad values)."""
    clock = clock_from_spec(args.clock, waits_only=False)
    if isinstance(clock, VirtualClock):
        raise ConfigError("--clock", args.clock, "allowed: real, paced:K (a served simulator "
                          "needs time that advances by itself)")  # fmt: skip
    if not 0 <= args.port <= 65535:
        raise ConfigError("--port", args.port, "allowed 0..65535")
    config = config_from_options(SimConfig, args, "gelrig sim serve mcr501", MCR501_OPTIONS)
    return clock, MCR501Simulator(clock, config)


def run(args: argparse.Namespace) -> int:
    clock, sim = build(args)
    server = SimulatorServer(sim, args.host, args.port).start()
    kind = "real time" if isinstance(clock, RealClock) else args.clock
    print(
        f"mcr501 simulator listening on {server.host}:{server.port} ({kind}); "
        f"VISA resource {server.resource}",
        flush=True,
    )
    deadline = time.monotonic() + args.duration
    try:
        while time.monotonic() < deadline:
            time.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    return 0
