"""The shear rig's twin: the simulated MCR 501 with the rig file's two spheres on its arm.

Everything the shear rig's physics needs lives in one instrument, so the twin is the
rheometer simulator built from the rig file's ``[simulator]`` truth as it is (the simulator's
configuration derives from the truth: :class:`~gelrig.simulators.mcr501.config.SimConfig`) on
the arm of its ``[rheometer]`` table. How a driver reaches it (TCP or an in-process link) is
the composition root's choice.
"""

from __future__ import annotations

from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.physics.truth import ShearSample
from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.mcr501.instrument import MCR501Simulator


def shear_simulator(clock: Clock, truth: ShearSample, rheometer: RheometerConfig
                    ) -> MCR501Simulator:
    """The simulated rheometer of a rig file: its ``[simulator]`` truth, its ``[rheometer]``
    table's arm."""
    return MCR501Simulator(clock, SimConfig.of(truth, rheometer))


__all__ = ["shear_simulator"]
