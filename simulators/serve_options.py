"""Command-line options of the served simulators (``gelrig sim serve NAME``), light to import.

``gelrig`` builds its whole parser on every call, so the options are declared here, apart from
the simulators (numpy, scipy, grpc), which are imported only when one is served. Each serve
module re-exports its ``add_arguments`` from here; defaults that come from the physics (the
paper's hold depth, the simulated load cell's noise and offset) are ``None`` here and resolved
by the serve module when it runs.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import NamedTuple

#: Port of the NI gRPC Device Server's default configuration.
USB6001_PORT = 31763


#: Which transport each public KDC101 client can use (shown by ``--help`` and in the README).
KDC101_CLIENTS = (
    "Clients: pylablib KinesisMotor needs --tcp (connect to ('serial', 'socket://HOST:PORT'); "
    "on a pty its serial backend fails setting RTS, errno 25). thorlabs-apt-device's KDC101 "
    "needs --pty (serial_port='/dev/pts/N'; it opens serial.Serial(port), which takes no "
    "socket:// URL). gelrig's "
    "driver works on all (socket://HOST:PORT, the pty path, or kdc101sim://NAME in process). "
    "One client at a time: a second TCP client is closed at once, as a busy serial port."
)


def kdc101_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``gelrig sim serve kdc101``."""
    if parser.epilog is None:
        parser.epilog = KDC101_CLIENTS
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST:PORT",
                       help="listen on TCP (port 0: any free); for pylablib and gelrig")
    where.add_argument("--pty", action="store_true",
                       help="create a pseudo-terminal; for thorlabs-apt-device and gelrig "
                            "(not pylablib: RTS fails on a pty)")
    parser.add_argument("--clock", default="real", help="real or paced:K (default real)")
    parser.add_argument("--serial", type=int, default=27000001, help="serial number (27xxxxxx)")
    parser.add_argument("--counts-per-mm", type=float, default=34554.96,
                        help="the actuator's true encoder scale")
    parser.add_argument("--travel", default="25 mm", help="actuator travel")
    parser.add_argument("--start-position", default="5 mm",
                        help="extension from the home switch at power-on")
    parser.add_argument("--home-offset", default="0.1 mm", help="home position past the switch")
    parser.add_argument("--direction", default="forward_is_negative",
                        choices=("forward_is_negative", "forward_is_positive"),
                        help="what APT 'forward' means (default: a KDC101's, forward_is_negative)")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many real seconds (default: until interrupted)")


def usb6001_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``gelrig sim serve usb6001``."""
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=int, default=USB6001_PORT,
                        help=f"TCP port (0: any free port; default {USB6001_PORT})")
    parser.add_argument("--clock", default="real", help="real, paced:K or virtual")
    parser.add_argument("--first-touch", default="2 mm",
                        help="stage position of the sphere's top (default 2 mm)")
    parser.add_argument("--plate-start", default="0 mm",
                        help="plate position at start (default 0 mm)")
    parser.add_argument("--ramp-speed", default="0 m/s",
                        help="plate speed into the sphere (default 0: the plate stays still)")
    parser.add_argument("--depth", default=None,
                        help="overlap where the ramp stops and the hold begins (default 6 %%)")
    parser.add_argument("--noise", default=None, help="rms input noise")
    parser.add_argument("--offset", default=None, help="conditioner zero offset")
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument("--buffer-size", type=int, default=None,
                        help="acquisition buffer in samples (default: DAQmx's rule)")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many real seconds (default: until interrupted)")


def mcr501_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``gelrig sim serve mcr501``."""
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=int, default=5025, help="TCP port (0: any free port)")
    parser.add_argument("--clock", default="real", help="real or paced:K (K x real time)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    parser.add_argument(
        "--lower-angle", default="0.8", help="lower sphere position (rad or '45 deg')"
    )
    parser.add_argument("--touch-gap", default="3 mm", help="gap where the spheres touch on top")
    parser.add_argument(
        "--duration", type=float, default=float("inf"), help="stop after this many real seconds"
    )


class ServedSimulator(NamedTuple):
    """A simulator ``gelrig sim serve`` reaches: its one-line help, options and serve module.

    ``module`` has ``run(args) -> int``; its docstring's first line is ``summary``.
    """

    summary: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    module: str


SERVED = {
    "kdc101": ServedSimulator(
        "Serve a simulated KDC101 + Z825B on its APT wire protocol over TCP or a pty.",
        kdc101_arguments, "simulators.kdc101.serve"),
    "usb6001": ServedSimulator(
        "Simulated NI USB-6001 (load-cell input) served as an NI gRPC Device Server.",
        usb6001_arguments, "simulators.usb6001.serve"),
    "mcr501": ServedSimulator(
        "Serve a simulated MCR 501 rheometer (two hydrogel spheres on the shear arm) over TCP.",
        mcr501_arguments, "simulators.mcr501.serve"),
}
