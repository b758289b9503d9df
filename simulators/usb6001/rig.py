"""The compression rig's force input, assembled: plate-on-sphere contact -> load-cell chain ->
the simulated USB-6001's input, all on one shared clock."""

from __future__ import annotations

from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.paper import PLATES, R_COMPRESSION
from gelrig.instrument.physics.plate_contact import (
    PlatePosition,
    PlatePositions,
    PlateSphereContact,
)
from gelrig.simulators.usb6001.config import DEFAULT_NOISE_RMS, SIM_OFFSET
from gelrig.simulators.usb6001.device import DeviceSpec, SimulatedUsb6001
from gelrig.simulators.usb6001.signals import LoadCellSignal

__all__ = ["PLATES", "SIM_OFFSET", "compression_daq"]


def compression_daq(
    clock: Clock,
    plate_position: PlatePosition | PlatePositions,
    first_touch: float,
    *,
    vectorized: bool = False,
    direction: int = 1,
    material: Material = PLATES,
    sphere_radius: float = R_COMPRESSION,
    chain: LoadCellChain | None = None,
    noise_rms: float = DEFAULT_NOISE_RMS,
    noise_drift: float = 0.0,
    noise_correlated: tuple[float, float] = (0.0, 1.0),
    seed: int = 0,
    channel: str = "ai0",
    spec: DeviceSpec | None = None,
    buffer_size: int | None = None,
    unloading: str = "cutoff",
) -> SimulatedUsb6001:
    """A simulated USB-6001 whose ``channel`` sees the load cell on the plate-sphere contact.

    ``plate_position(t)`` (m) is the stage's plate position on ``clock``; ``first_touch`` (m)
    the stage position where the plate meets the sphere's top (see
    gelrig.instrument.physics.plate_contact for
    the sign convention). ``chain`` is the simulated rig's true chain (default: the nominal
    chain with a :data:`SIM_OFFSET` conditioner offset). ``unloading``: the contact model on
    unloading, ``"cutoff"`` (the paper's) or ``"mdr"`` (physics.md 1b).
    """
    contact = PlateSphereContact(
        material, sphere_radius, first_touch, plate_position,
        direction=direction, vectorized=vectorized, unloading=unloading,
    )
    signal = LoadCellSignal(contact, chain or LoadCellChain(offset=SIM_OFFSET), noise_rms, seed,
                            noise_drift, noise_correlated)
    return SimulatedUsb6001(clock, {channel: signal}, spec=spec, buffer_size=buffer_size)
