"""The MCR 501 driver on its simulator through pyvisa-py over TCP, for the driver tests."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from gelrig.drivers.mcr501 import MCR501
from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer


@dataclass
class Rig:
    clock: VirtualClock
    sim: MCR501Simulator
    server: SimulatorServer
    drv: MCR501

    def turn(self, seconds: float) -> None:
        """Let ``seconds`` pass while the arm turns, renewing the rotation as gelrig's waits do
        (ADR 0201): without renewals the instrument stops it after 1.5 s."""
        keep_moving(self.clock, self.drv, seconds, self.drv.config.motion_bound)

    def arm_stopped(self) -> bool:
        """The simulated motor has a zero set speed and has come to rest."""
        now = self.clock.now()
        self.clock.sleep(1.0)  # allow for the deceleration ramp
        _, omega = self.sim.cell.spin.state(self.clock.now())
        return self.sim.cell.spin.target == 0.0 and omega == 0.0 and now < self.clock.now()


@contextmanager
def rig(
    rm: Any, sim_config: SimConfig | None = None, config: RheometerConfig | None = None
) -> Iterator[Rig]:
    """A simulator on a TCP server in this process, sharing a VirtualClock with the driver."""
    clock = VirtualClock()
    sim = MCR501Simulator(clock, sim_config if sim_config is not None else SimConfig())
    with SimulatorServer(sim) as server:
        drv = MCR501(server.resource, clock, config, resource_manager=rm).open()
        try:
            yield Rig(clock, sim, server, drv)
        finally:
            drv.close()
