"""The rigs as the runner sees them: instruments behind their contracts, a clock, the limits.

Built by the rig factory (gelrig.factory) from a rig file; a test may build one from doubles.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

from instrument.clock import Clock
from instrument.loadcell import ForceSensor
from instrument.rheometer import Rheometer
from instrument.stage import Stage

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CompressionLimits:
    """Interlock limits of the plate-compression rig (SI)."""

    max_force: float = 2.0  # N, below the 2.5 N load cell's capacity
    max_overlap: float = 2.5e-3  # m past first touch
    fast_speed: float = 1e-3  # m/s, for moves away from the sphere
    acceleration: float = 4e-3  # m/s^2


@dataclass(frozen=True)
class ShearLimits:
    """Interlock limits of the shear rig (SI)."""

    max_torque: float = 5e-3  # N m
    max_normal_force: float = 2.0  # N
    max_overlap: float = 1.2e-3  # m below the touch gap


@dataclass
class CompressionRig:
    """Stage + force sensor of the plate-compression rig."""

    stage: Stage
    force: ForceSensor
    clock: Clock
    limits: CompressionLimits = field(default_factory=CompressionLimits)
    identities: dict[str, object] = field(default_factory=dict)
    simulated: bool = False
    close_hooks: list[Callable[[], None]] = field(default_factory=list)

    kind = "compression"

    def stop_all(self) -> None:
        """Stop every motion at once; never raises (it runs on the way out of faults)."""
        try:
            self.stage.stop(immediate=True)
        except Exception:
            log.exception("stage stop failed")

    def close(self) -> None:
        self.stop_all()
        _run_all((self.force.stop, self.force.close, self.stage.close, *self.close_hooks))


@dataclass
class ShearRig:
    """The rheometer of the inter-particle shear rig."""

    rheometer: Rheometer
    clock: Clock
    limits: ShearLimits = field(default_factory=ShearLimits)
    identities: dict[str, object] = field(default_factory=dict)
    simulated: bool = False
    close_hooks: list[Callable[[], None]] = field(default_factory=list)

    kind = "shear"

    def stop_all(self) -> None:
        try:
            self.rheometer.stop()
        except Exception:
            log.exception("rheometer stop failed")

    def close(self) -> None:
        self.stop_all()
        _run_all((self.rheometer.close, *self.close_hooks))


def _run_all(closers: tuple[Callable[[], None], ...]) -> None:
    """Call every closer even if some fail (each failure is logged): release everything."""
    for closer in closers:
        try:
            closer()
        except Exception:
            log.exception("closing %r failed", closer)


Rig = CompressionRig | ShearRig
