"""Simulated Anton Paar MCR 501 with two hydrogel spheres on the shear arm.

Serves the driver's command table over TCP (:class:`SimulatorServer`) or straight in-process
(:class:`DirectLink`); the state follows the injected clock lazily (docs/decisions/0023).
"""

from simulators.mcr501.config import PAPER_MATERIAL, SimConfig
from simulators.mcr501.faults import FaultPlan
from simulators.mcr501.instrument import MCR501Simulator
from simulators.mcr501.link import DirectLink
from simulators.mcr501.physics import Forces, Sample, ShearCell, Trip
from simulators.mcr501.server import SimulatorServer

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
