"""What the simulated MCR 501 shear rig is: spheres, material, hidden geometry, sensor chain.

Defaults are the paper's shear-rig numbers (physics.md section 4): R1 = 9.2 mm on the arm,
R2 = 9.96 mm fixed, G_e = 4 kPa, one relaxation term G_l = 5 G_e with tau = 2000 s (the F_h fit;
one material serves both forces), mu = 5e-3, arm 27 mm. The instrument limits and the sensor
chain (resolution, noise, offset, acceleration) are UNVERIFIED placeholders, chosen so that the
paper's features stay resolvable. ``lower_angle`` and ``touch_gap`` are hidden from protocols:
they must find them by contact search.

Each pass is a fresh contact (physics.md section 1): ``carry_history`` keeps the hereditary
state across separations instead, a sensitivity option (docs/decisions/0140). The paper's
anisotropy: ``material_vertical`` gives the F_v its own modulus (the paper fits F_v with
G_l = 4 G_e and F_h with 5 G_e); by default one material serves both forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from instrument.contact import Material
from instrument.contact_models import UNLOADING_MODELS
from instrument.errors import ConfigError

PAPER_MATERIAL = Material.of(4e3, [(2e4, 2000.0)], nu=0.5)


@dataclass(frozen=True)
class SimConfig:
    """Parameters of the simulated rig (SI units; angles in rad, counted clockwise)."""

    r1: float = 9.2e-3
    r2: float = 9.96e-3
    material: Material = PAPER_MATERIAL
    #: Material whose F_perp gives F_v (the paper's anisotropy); None: ``material``.
    material_vertical: Material | None = None
    #: Normal-contact model on unloading: "cutoff" (the paper's) or "mdr" (physics.md 1b).
    unloading: str = "cutoff"
    #: Keep the hereditary state across separations (sensitivity option; off: fresh contact).
    carry_history: bool = False
    mu: float = 5e-3
    arm: float = 0.027
    #: Angular position of the lower sphere's centre (hidden).
    lower_angle: float = 0.8
    #: Gap at which the surfaces touch with the upper sphere on top of the lower (hidden).
    touch_gap: float = 3.0e-3
    start_angle: float = 0.0
    start_gap: float = 10e-3
    #: The gap must be referenced (``:GAPZ[]``) before gap moves, as after power-up.
    start_referenced: bool = False
    acceleration: float = 0.5  # rad/s^2, UNVERIFIED
    lift_speed: float = 1e-3  # m/s, UNVERIFIED
    max_rpm: float = 100.0  # UNVERIFIED
    gap_min: float = 0.0
    gap_max: float = 0.05
    #: Overlap at which the instrument trips on normal-force overload (code 31).
    overlap_limit: float = 1.2e-3
    torque_range: float = 0.2  # N m, UNVERIFIED
    torque_resolution: float = 1e-9  # N m
    torque_noise: float = 1e-7  # N m, standard deviation
    #: Bearing drag added to the motor torque while turning, in the direction of motion.
    torque_offset: float = 2e-6  # N m
    normal_force_range: float = 50.0  # N, UNVERIFIED
    normal_force_resolution: float = 1e-5  # N
    normal_force_noise: float = 2e-5  # N, standard deviation
    seed: int = 0
    #: Integration grid: at most this arc (m) of arm or lift travel per step ...
    substep_travel: float = 1e-6
    #: ... and at most this long (s) per step.
    max_substep: float = 1.0
    #: Points the stream holds; beyond it the oldest are dropped and the overflow flag (0x20)
    #: latches until ``:RUN`` or ``:END`` (UNVERIFIED; docs/decisions/0110): 4.1 s at the
    #: fastest interval (1 ms), 410 s at the ladder's default 0.1 s.
    stream_buffer: int = 4096
    identity: tuple[str, str, str] = field(default=("MCR501", "SN80000000", "03.40"))

    def __post_init__(self) -> None:
        positive = (
            "r1", "r2", "arm", "acceleration", "lift_speed", "max_rpm", "overlap_limit",
            "torque_range", "torque_resolution", "normal_force_range",
            "normal_force_resolution", "substep_travel", "max_substep",
        )  # fmt: skip
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(name, value, "must be > 0")
        for name in ("mu", "torque_noise", "torque_offset", "normal_force_noise", "gap_min"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(name, value, "must be >= 0")
        if not self.gap_min < self.gap_max:
            raise ConfigError("gap_max", self.gap_max, f"must be > gap_min = {self.gap_min:g} m")
        if not self.gap_min <= self.start_gap <= self.gap_max:
            raise ConfigError(
                "start_gap", self.start_gap, f"allowed [{self.gap_min:g}, {self.gap_max:g}] m"
            )
        if not self.touch_gap - self.gap_min < self.r1 + self.r2:
            raise ConfigError(
                "touch_gap", self.touch_gap, "must lie less than R1 + R2 above gap_min"
            )
        if self.unloading not in UNLOADING_MODELS:
            raise ConfigError("unloading", self.unloading,
                              f"allowed: {', '.join(UNLOADING_MODELS)}")
        if self.stream_buffer < 1:
            raise ConfigError("stream_buffer", self.stream_buffer, "must be >= 1")

    @property
    def s(self) -> float:
        """R1 + R2 (m)."""
        return self.r1 + self.r2
