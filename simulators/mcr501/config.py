"""What the simulated MCR 501 shear rig is: spheres, material, hidden geometry, sensor chain.

The sample's fields (radii, material, friction, the hidden ``lower_angle`` and ``touch_gap``,
the noise, the contact model) are the rig file's ``[simulator]`` truth:
:class:`SimConfig` derives from :class:`~gelrig.instrument.physics.truth.ShearSample`, so each
is declared once, with the paper's shear-rig numbers as defaults (physics.md section 4): R1 =
9.2 mm on the arm, R2 = 9.96 mm fixed, G_e = 4 kPa, one relaxation term G_l = 5 G_e with tau =
2000 s (the F_h fit; one material serves both forces), mu = 5e-3. The instrument's own ranges
and resolutions are the ``[rheometer]`` table's declarations (UNVERIFIED placeholders, chosen
so that the paper's features stay resolvable), the arm too (27 mm). ``lower_angle`` and
``touch_gap`` are hidden from protocols: they must find them by contact search.

Each pass is a fresh contact (physics.md section 1): ``carry_history`` keeps the hereditary
state across separations instead, a sensitivity option (docs/decisions/0140). The paper's
anisotropy: ``material_vertical`` gives the F_v its own modulus (the paper fits F_v with
G_l = 4 G_e and F_h with 5 G_e); by default one material serves both forces.

Light to import (no numpy): ``gelrig sim serve mcr501`` builds its options from these fields.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.fields import Field, Flag, Where, param
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.truth import SEED, ShearSample

#: The paper's shear material (the F_h fit), the default of :class:`SimConfig`.
PAPER_MATERIAL = paper.SHEAR_FH

#: The instrument's fields declared by the rig file's ``[rheometer]`` table.
_RHEOMETER = RheometerConfig.specs()


@dataclass(frozen=True)
class SimConfig(ShearSample):
    """Parameters of the simulated rig (SI units; angles in rad, counted clockwise)."""

    exact_integers: ClassVar[bool] = True

    seed: int = param(SEED)  # the truth's field, held as an int (numpy's generators take one)
    arm: float = param(_RHEOMETER["arm"])
    start_angle: float = param(Field("start_angle", "rad", 0.0,
                                     help="arm angle at power-on"))
    start_gap: float = param(Field("start_gap", "m", 10e-3, display="mm",
                                   help="gap at power-on"))
    #: The gap must be referenced (``:GAPZ[]``) before gap moves, as after power-up.
    start_referenced: bool = param(Flag("start_referenced", False,
                                        help="gap referenced at power-on"))
    acceleration: float = param(Field("acceleration", "rad/s^2", 0.5, 0.0, lo_open=True,
                                      help="arm acceleration (UNVERIFIED)"))
    lift_speed: float = param(Field("lift_speed", "m/s", 1e-3, 0.0, lo_open=True,
                                    display="mm/s", help="gap speed (UNVERIFIED)"))
    max_rpm: float = param(Field("max_rpm", "rpm", 100.0, 0.0, lo_open=True,
                                 help="highest arm speed (UNVERIFIED)"))
    gap_min: float = param(_RHEOMETER["gap_min"])
    gap_max: float = param(_RHEOMETER["gap_max"])
    #: Overlap at which the instrument trips on normal-force overload (code 31).
    overlap_limit: float = param(_RHEOMETER["overlap_limit"])
    torque_range: float = param(_RHEOMETER["torque_range"])
    torque_resolution: float = param(_RHEOMETER["torque_resolution"])
    #: Bearing drag added to the motor torque while turning, in the direction of motion.
    torque_offset: float = param(Field("torque_offset", "N*m", 2e-6, 0.0,
                                       help="bearing drag while turning"))
    normal_force_range: float = param(_RHEOMETER["normal_force_range"])
    normal_force_resolution: float = param(_RHEOMETER["normal_force_resolution"])
    #: Integration grid: at most this arc (m) of arm or lift travel per step ...
    substep_travel: float = param(Field("substep_travel", "m", 1e-6, 0.0, lo_open=True,
                                        help="integration step: arc or lift per step"))
    #: ... and at most this long (s) per step.
    max_substep: float = param(Field("max_substep", "s", 1.0, 0.0, lo_open=True,
                                     help="integration step: longest step"))
    #: Points the stream holds; beyond it the oldest are dropped and the overflow flag (0x20)
    #: latches until ``:RUN`` or ``:END`` (UNVERIFIED; docs/decisions/0110): 4.1 s at the
    #: fastest interval (1 ms), 410 s at the ladder's default 0.1 s.
    stream_buffer: int = param(Field("stream_buffer", "", 4096, 1, integer=True,
                                     help="points the stream holds (UNVERIFIED)"))
    identity: tuple[str, str, str] = field(default=("MCR501", "SN80000000", "03.40"))

    @classmethod
    def of(cls, truth: ShearSample, rheometer: RheometerConfig | None = None,
           **changes: Any) -> SimConfig:
        """The simulated rig of a rig file: its ``[simulator]`` truth as it is, on the arm of
        its ``[rheometer]`` table; ``changes`` set other fields."""
        sample = {f.name: getattr(truth, f.name) for f in dataclasses.fields(ShearSample)}
        if rheometer is not None:
            sample["arm"] = rheometer.arm
        return cls(**{**sample, **changes})

    def validate(self, where: Where) -> None:
        if not self.gap_min < self.gap_max:
            raise where.error("gap_max", self.gap_max, f"must be > gap_min = {self.gap_min:g} m")
        if not self.gap_min <= self.start_gap <= self.gap_max:
            raise where.error("start_gap", self.start_gap,
                              f"allowed [{self.gap_min:g}, {self.gap_max:g}] m")
        if not self.touch_gap - self.gap_min < self.r1 + self.r2:
            raise where.error("touch_gap", self.touch_gap,
                              "must lie less than R1 + R2 above gap_min")

    @property
    def s(self) -> float:
        """R1 + R2 (m)."""
        return self.r1 + self.r2
