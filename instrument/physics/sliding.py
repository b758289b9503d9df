"""Geometry and Coulomb friction of one sphere sliding past another (physics.md section 2).

Lower sphere (R2) fixed, upper sphere (R1) on the rheometer arm; the arc is treated as a
straight line. ``psi`` is the horizontal offset of the moving centre ahead of the fixed one,
in the direction of motion: ``psi > 0`` approaching, ``0`` on top, ``< 0`` departing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import FloatArray, Material, effective_radius
from gelrig.instrument.physics.contact_models import make_contact


@dataclass(frozen=True)
class SlidingGeometry:
    """Two spheres passing at a fixed vertical centre distance ``h = R1 + R2 - delta_max``."""

    r1: float
    r2: float
    delta_max: float

    def __post_init__(self) -> None:
        for name, value in (("R1", self.r1), ("R2", self.r2), ("delta_max", self.delta_max)):
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(name, value, "must be > 0 m")
        if self.delta_max >= self.r1 + self.r2:
            raise ConfigError(
                "delta_max", self.delta_max, f"must be < R1 + R2 = {self.r1 + self.r2:g} m"
            )

    @property
    def s(self) -> float:
        """Centre distance at first touch, R1 + R2 (m)."""
        return self.r1 + self.r2

    @property
    def h(self) -> float:
        """Vertical centre distance during the pass (m)."""
        return self.s - self.delta_max

    @property
    def psi0(self) -> float:
        """Horizontal centre offset at first touch (m)."""
        return math.sqrt(self.s**2 - self.h**2)

    @property
    def l_g(self) -> float:
        """Geometric contact length 2 psi0 (m)."""
        return 2.0 * self.psi0

    @property
    def radius(self) -> float:
        """Effective radius of the pair (m)."""
        return effective_radius(self.r1, self.r2)

    def distance(self, psi: ArrayLike) -> FloatArray:
        """Centre-to-centre distance d = sqrt(h^2 + psi^2) (m)."""
        return np.hypot(self.h, np.asarray(psi, dtype=float))

    def overlap(self, psi: ArrayLike) -> FloatArray:
        """Overlap delta = S - d (m); negative when apart."""
        return self.s - self.distance(psi)


def resolve_forces(
    f_perp: ArrayLike, psi: ArrayLike, h: float, mu: float
) -> tuple[FloatArray, FloatArray]:
    """Resolve F_perp with Coulomb friction into (F_h, F_v), physics.md section 2.

    ``F_h = F_perp (psi + mu h) / d`` resists the motion (+ approaching, - departing);
    ``F_v = F_perp (h - mu psi) / d`` pushes the spheres apart. In the lab frame, a pass in
    the opposite direction mirrors: the same formulas with ``psi`` measured along that
    motion, and the lab-frame sign of the torque reversed.
    """
    if not mu >= 0:
        raise ConfigError("mu", mu, "friction coefficient must be >= 0")
    f = np.asarray(f_perp, dtype=float)
    p = np.asarray(psi, dtype=float)
    d = np.hypot(h, p)
    return f * (p + mu * h) / d, f * (h - mu * p) / d


def rpm_from_speed(speed: float, arm: float) -> float:
    """Rotation rate (rpm) that moves the arm tip at ``speed`` (m/s): v / (2 pi L) * 60."""
    return speed / (2.0 * math.pi * arm) * 60.0


def speed_from_rpm(rpm: float, arm: float) -> float:
    """Linear speed (m/s) at the arm tip for a rotation rate in rpm."""
    return rpm * 2.0 * math.pi * arm / 60.0


@dataclass(frozen=True)
class ShearPass:
    """One modelled pass: arrays over time (s) with overlap, forces (N) and offset (m)."""

    t: FloatArray
    psi: FloatArray
    delta: FloatArray
    f_perp: FloatArray
    f_h: FloatArray
    f_v: FloatArray

    @property
    def theta(self) -> FloatArray:
        """Travel of the moving centre from the start of the pass (m), the paper's theta."""
        return self.psi[0] - self.psi


def shear_pass(
    geometry: SlidingGeometry,
    material: Material,
    speed: float,
    mu: float = 0.0,
    dt: float | None = None,
    margin: float = 0.0,
    material_vertical: Material | None = None,
    unloading: str = "cutoff",
) -> ShearPass:
    """Model one pass at constant ``speed`` from psi0 + margin to -(psi0 + margin).

    ``dt`` defaults to the time for 1/2000 of the travel. The contact has no prior history
    (each pass is a fresh contact). ``material_vertical`` gives F_v its own modulus (the
    paper's anisotropy; ``f_perp`` stays the horizontal material's); ``unloading`` picks the
    contact model (:func:`gelrig.instrument.physics.contact_models.make_contact`).
    """
    if not (math.isfinite(speed) and speed > 0):
        raise ConfigError("speed", speed, "must be > 0 m/s")
    if not margin >= 0:
        raise ConfigError("margin", margin, "must be >= 0 m")
    start = geometry.psi0 + margin
    duration = 2.0 * start / speed
    if dt is None:
        dt = duration / 2000.0
    if not (math.isfinite(dt) and dt > 0):
        raise ConfigError("dt", dt, "must be > 0 s")
    n = math.floor(duration / dt + 1e-9) + 1
    t = np.arange(n, dtype=float) * dt
    psi = start - speed * t
    delta = geometry.overlap(psi)
    f_perp = make_contact(material, geometry.radius, unloading).block(t, delta)
    f_h, f_v = resolve_forces(f_perp, psi, geometry.h, mu)
    if material_vertical is not None:
        f_perp_v = make_contact(material_vertical, geometry.radius, unloading).block(t, delta)
        f_v = resolve_forces(f_perp_v, psi, geometry.h, mu)[1]
    return ShearPass(t, np.asarray(psi, dtype=float), delta, f_perp, f_h, f_v)
