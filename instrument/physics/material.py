"""The hydrogel's viscoelastic material: a relaxing modulus as a Prony series.

Light to import (no numpy until a modulus is evaluated): the rig file's typed truth, the
paper's reference numbers and the simulators' option tables declare their defaults with it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from gelrig.instrument.core.errors import ConfigError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from gelrig.instrument.core.arrays import FloatArray


@dataclass(frozen=True)
class RelaxationTerm:
    """One Prony term of the relaxing modulus: amplitude ``g`` (Pa), time ``tau`` (s)."""

    g: float
    tau: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.g) and self.g >= 0):
            raise ConfigError("relax G", self.g, "must be a finite modulus >= 0 Pa")
        if not (math.isfinite(self.tau) or self.tau == math.inf) or not self.tau > 0:
            raise ConfigError("relax tau", self.tau, "must be > 0 s")


@dataclass(frozen=True)
class Material:
    """Viscoelastic hydrogel: ``G(t) = g_e + sum g_i exp(-t/tau_i)``, Poisson ratio ``nu``."""

    g_e: float
    relax: tuple[RelaxationTerm, ...] = ()
    nu: float = 0.5

    def __post_init__(self) -> None:
        if not (math.isfinite(self.g_e) and self.g_e > 0):
            raise ConfigError("G_e", self.g_e, "must be a finite modulus > 0 Pa")
        if not (0 <= self.nu < 1):
            raise ConfigError("nu", self.nu, "Poisson ratio must satisfy 0 <= nu < 1")
        object.__setattr__(self, "relax", tuple(self.relax))

    @classmethod
    def of(cls, g_e: float, relax: Sequence[tuple[float, float]] = (), nu: float = 0.5) -> Material:
        """Shorthand: ``Material.of(4e3, [(2e4, 2000.0)])``."""
        return cls(g_e, tuple(RelaxationTerm(g, tau) for g, tau in relax), nu)

    @property
    def g_instant(self) -> float:
        """Modulus at t = 0 (all terms unrelaxed)."""
        return self.g_e + sum(t.g for t in self.relax)

    def modulus(self, t: ArrayLike) -> FloatArray:
        """Relaxation modulus G(t) in Pa."""
        import numpy as np

        t = np.asarray(t, dtype=float)
        out = np.full_like(t, self.g_e)
        for term in self.relax:
            out += term.g * np.exp(-t / term.tau)
        return out
