"""What the ladder fit takes as given (:class:`FitSetup`), declared like every configuration.

A :class:`~gelrig.instrument.core.fields.Config` (ADR 0052): each field with its unit, default,
range and help. The radii, Poisson ratio, unloading model and carry-history switch are the rig
file's ``[simulator]`` declarations (:mod:`gelrig.instrument.physics.truth`) and the arm
defaults to the paper's (:data:`gelrig.instrument.physics.paper.ARM`), so their defaults are
written once; a campaign's ``[analysis]`` table (``gelrig.campaign.spec``) shares the fit's
own (:data:`TERMS`, :data:`ANISOTROPIC`, :data:`FIT_GEOMETRY`). Light to import (no numpy).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.core.fields import Config, Field, Flag, param
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.truth import CARRY_HISTORY, NU, R1, R2, UNLOADING

#: Samples of a pass that enter the fit at most (a uniform stride over its contact window).
MAX_POINTS_PER_PASS = 300

TERMS = Field("terms", "", 1, 1, 2, integer=True, help="relaxation terms fitted")
ANISOTROPIC = Flag("anisotropic", False,
                   help="fit the relaxation amplitudes separately for F_h and F_v (the "
                        "paper's anisotropy, docs/decisions/0142)")
FIT_GEOMETRY = Flag("fit_geometry", True,
                    help="fit the touch gap and the lower sphere's angle too (else the "
                         "contact search's are taken)")


@dataclass(frozen=True)
class FitSetup(Config):
    """What the fit takes as given: radii (m), arm (m), Poisson ratio, number of terms, and
    the model's options: separate F_h and F_v amplitudes (``anisotropic``), the unloading
    model, and whether the history is carried across separations (off: fresh contacts)."""

    section: ClassVar[str] = "fit"
    exact_integers: ClassVar[bool] = True

    r1: float = param(R1)
    r2: float = param(R2)
    arm: float = param(Field("arm", "m", paper.ARM, 1e-3, 0.5, help="arm length",
                             display="mm"))
    nu: float = param(NU)
    terms: int = param(TERMS)
    fit_geometry: bool = param(FIT_GEOMETRY)
    max_points_per_pass: int = param(Field("max_points_per_pass", "", MAX_POINTS_PER_PASS, 2,
                                           1e6, integer=True,
                                           help="samples of a pass in the fit at most"))
    anisotropic: bool = param(ANISOTROPIC)
    unloading: str = param(UNLOADING)
    carry_history: bool = param(CARRY_HISTORY)

    @property
    def s(self) -> float:
        return self.r1 + self.r2
