"""Simulated Anton Paar MCR 501 with two hydrogel spheres on the shear arm.

Serves the driver's command table over TCP (:class:`SimulatorServer`) or straight in-process
(:class:`DirectLink`); the state follows the injected clock lazily (docs/decisions/0023).
The names below are imported on first use, so that the configuration
(:mod:`gelrig.simulators.mcr501.config`, what ``gelrig --help`` shows) loads without numpy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gelrig.simulators.mcr501.config import PAPER_MATERIAL, SimConfig
    from gelrig.simulators.mcr501.faults import FaultPlan
    from gelrig.simulators.mcr501.instrument import MCR501Simulator
    from gelrig.simulators.mcr501.link import DirectLink
    from gelrig.simulators.mcr501.physics import Forces, Sample, ShearCell, Trip
    from gelrig.simulators.mcr501.server import SimulatorServer

#: public name -> the module (in this package) that defines it
_LAZY = {
    "PAPER_MATERIAL": "config", "SimConfig": "config", "FaultPlan": "faults",
    "MCR501Simulator": "instrument", "DirectLink": "link", "Forces": "physics",
    "Sample": "physics", "ShearCell": "physics", "Trip": "physics", "SimulatorServer": "server",
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)


__all__ = [
    "PAPER_MATERIAL",
    "DirectLink",
    "FaultPlan",
    "Forces",
    "MCR501Simulator",
    "Sample",
    "ShearCell",
    "SimConfig",
    "SimulatorServer",
    "Trip",
]
