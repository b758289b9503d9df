"""The plate-compression experiment in the model: ramp a rigid plate into a sphere, then hold.

Plate-sphere contact: R = R_sphere (physics.md section 3). Time starts at first touch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import FloatArray, Material, hertz_prefactor
from gelrig.instrument.physics.contact_models import make_contact


@dataclass(frozen=True)
class RampHold:
    """A modelled ramp-and-hold record: time (s), overlap (m), force (N)."""

    t: FloatArray
    delta: FloatArray
    force: FloatArray
    t_hold: float


def ramp_hold_overlap(t: FloatArray, depth: float, speed: float) -> FloatArray:
    """Overlap of a plate moving at ``speed`` from first touch (t = 0) to ``depth``, then held."""
    return np.minimum(speed * np.asarray(t, dtype=float), depth)


def ramp_hold(
    radius: float,
    depth: float,
    speed: float,
    hold: float,
    material: Material,
    dt: float = 0.01,
) -> RampHold:
    """Model a ramp from first touch at ``speed`` (m/s) to ``depth`` (m), then a ``hold`` (s).

    Samples every ``dt`` (s); the end of the ramp is always a sample so the hold starts exactly.
    """
    for name, value, unit in (
        ("radius", radius, "m"),
        ("depth", depth, "m"),
        ("speed", speed, "m/s"),
        ("dt", dt, "s"),
    ):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(name, value, f"must be > 0 {unit}")
    if not (math.isfinite(hold) and hold >= 0):
        raise ConfigError("hold", hold, "must be >= 0 s")
    if depth >= radius:
        raise ConfigError("depth", depth, f"must be < the sphere radius {radius:g} m")
    hertz_prefactor(radius, material.nu)
    t_ramp = depth / speed
    n_ramp = max(1, math.ceil(t_ramp / dt - 1e-9))
    ramp_t = np.linspace(0.0, t_ramp, n_ramp + 1)
    n_hold = math.floor(hold / dt + 1e-9)
    hold_t = t_ramp + dt * np.arange(1, n_hold + 1)
    t = np.concatenate((ramp_t, hold_t))
    delta = ramp_hold_overlap(t, depth, speed)
    force = make_contact(material, radius).block(t, delta)
    return RampHold(t, delta, force, t_ramp)
