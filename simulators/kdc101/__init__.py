"""Simulated Thorlabs KDC101 + Z825B speaking APT: in process (``kdc101sim://NAME``) or served
over TCP / a pty (``gelrig sim serve kdc101``).

The names below are imported on first use, so that the configuration
(:mod:`gelrig.simulators.kdc101.config`, what ``gelrig --help`` shows) loads without the
simulator and numpy. The ``kdc101sim://`` URL handler is installed when the transport module
loads (as :func:`register` is reached).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gelrig.instrument.core.motion import Trajectory, trapezoid_duration
    from gelrig.simulators.kdc101.config import SimConfig
    from gelrig.simulators.kdc101.device import KDC101Simulator
    from gelrig.simulators.kdc101.protocol_kdc101sim import install, register, unregister

#: public name -> the module (in this package, or a full name) that defines it
_LAZY = {
    "KDC101Simulator": "device", "SimConfig": "config",
    "Trajectory": "gelrig.instrument.core.motion",
    "trapezoid_duration": "gelrig.instrument.core.motion", "install": "protocol_kdc101sim",
    "register": "protocol_kdc101sim", "unregister": "protocol_kdc101sim",
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = _LAZY[name]
    return getattr(importlib.import_module(module if "." in module
                                           else f"{__name__}.{module}"), name)


__all__ = [
    "KDC101Simulator",
    "SimConfig",
    "Trajectory",
    "install",
    "register",
    "trapezoid_duration",
    "unregister",
]
