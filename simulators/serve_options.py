"""Command-line options of the served simulators (``gelrig sim serve NAME``), light to import.

``gelrig`` builds its whole parser on every call, so the options are declared here, apart from
the simulators (numpy, scipy, grpc), which are imported only when one is served; the
configurations the options come from are imported when the options are added (``gelrig``
adds them when ``sim serve NAME`` is parsed or asked for its help). Each serve module
re-exports its ``add_arguments`` from here. The options of the simulated hardware and
sample are the simulators' configuration fields (``simulators/*/config.py``, the rig file's
``[simulator]`` truth): names, units, defaults and help come from the one declaration of each
(:mod:`gelrig.instrument.core.options`), so ``--help`` shows the defaults the rig file
documents; the serve module reads them back with
:func:`~gelrig.instrument.core.options.config_from_options`.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import NamedTuple

#: Port of the NI gRPC Device Server's default configuration.
USB6001_PORT = 31763

#: The MCR 501 simulator's fields offered as options: the sample (the rig file's
#: ``[simulator]`` truth, :class:`~gelrig.instrument.physics.truth.ShearSample`) and the arm
#: (the ``[rheometer]`` table's).
MCR501_OPTIONS = ("r1", "r2", "mu", "lower_angle", "touch_gap", "seed", "unloading",
                  "torque_noise", "normal_force_noise", "carry_history", "arm")


#: Which transport each public KDC101 client can use (shown by ``--help`` and in the README).
KDC101_CLIENTS = (
    "Clients: pylablib KinesisMotor needs --tcp (connect to ('serial', 'socket://HOST:PORT'); "
    "on a pty its serial backend fails setting RTS, errno 25). thorlabs-apt-device's KDC101 "
    "needs --pty (serial_port='/dev/pts/N'; it opens serial.Serial(port), which takes no "
    "socket:// URL). gelrig's "
    "driver works on all (socket://HOST:PORT, the pty path, or kdc101sim://NAME in process). "
    "One client at a time: a second TCP client is closed at once, as a busy serial port."
)
#: Values are SI numbers or numbers with a unit, as in a rig file.
_UNITS = "values: SI numbers, or with a unit as in a rig file ('0.1 mm', '45 deg')"


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
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many real seconds (default: until interrupted)")
    from gelrig.instrument.core.options import add_options
    from gelrig.simulators.kdc101.config import SimConfig

    add_options(parser.add_argument_group("the simulated controller and actuator", _UNITS),
                SimConfig)


def usb6001_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``gelrig sim serve usb6001``."""
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=int, default=USB6001_PORT,
                        help=f"TCP port (0: any free port; default {USB6001_PORT})")
    parser.add_argument("--clock", default="real", help="real, paced:K or virtual")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many real seconds (default: until interrupted)")
    from gelrig.instrument.core.options import add_options
    from gelrig.simulators.usb6001.config import Standalone

    add_options(parser.add_argument_group("the plate, the sphere and the input", _UNITS),
                Standalone)


def mcr501_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``gelrig sim serve mcr501``."""
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=int, default=5025, help="TCP port (0: any free port)")
    parser.add_argument("--clock", default="real", help="real or paced:K (K x real time)")
    parser.add_argument(
        "--duration", type=float, default=float("inf"), help="stop after this many real seconds"
    )
    from gelrig.instrument.core.options import add_options
    from gelrig.simulators.mcr501.config import SimConfig

    add_options(parser.add_argument_group("the sample (the rig file's [simulator] table) and "
                                          "the arm", _UNITS), SimConfig, MCR501_OPTIONS)


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
        kdc101_arguments, "gelrig.simulators.kdc101.serve"),
    "usb6001": ServedSimulator(
        "Simulated NI USB-6001 (load-cell input) served as an NI gRPC Device Server.",
        usb6001_arguments, "gelrig.simulators.usb6001.serve"),
    "mcr501": ServedSimulator(
        "Serve a simulated MCR 501 rheometer (two hydrogel spheres on the shear arm) over TCP.",
        mcr501_arguments, "gelrig.simulators.mcr501.serve"),
}
