"""What the simulated USB-6001's force input is, standing alone (``gelrig sim serve usb6001``).

In a composed rig the plate is the stage simulator's (``gelrig.simulators.twins``) and the
sample the rig file's ``[simulator]`` truth. Served alone, the plate follows a ramp and hold of
its own into the paper's sphere, read through the nominal load-cell chain: :class:`Standalone`,
a :class:`~gelrig.instrument.core.fields.Config` whose fields are the command's options. The
conditioner offset and the input noise of the simulated chain are declared once, here. Light
to import (no numpy).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.fields import Config, Field, param
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.truth import SEED, TIMING, CompressionTruth

#: Conditioner offset of the simulated rig (V): nonzero so that a missing tare shows.
SIM_OFFSET = 0.0123
#: Default rms noise at the ADC input (V): about one 14-bit code over +-10 V (UNVERIFIED).
DEFAULT_NOISE_RMS = 1e-3


@dataclass(frozen=True)
class Standalone(Config):
    """The plate's own ramp and hold, where the sphere sits, and the input's noise and offset.

    ``first_touch`` is the rig file's field, at 2 mm (a plate at rest from 0 mm is clear of the
    sphere); ``offset`` the load-cell chain's, at :data:`SIM_OFFSET`.
    """

    section: ClassVar[str] = "usb6001"
    exact_integers: ClassVar[bool] = True

    first_touch: float = param(dataclasses.replace(
        CompressionTruth.specs()["first_touch"], default=2e-3))  # type: ignore[type-var]
    plate_start: float = param(Field("plate_start", "m", 0.0, display="mm",
                                     help="plate position at start"))
    ramp_speed: float = param(Field("ramp_speed", "m/s", 0.0, 0.0, display="mm/s",
                                    help="plate speed into the sphere (0: the plate stays "
                                         "still)"))
    depth: float = param(Field("depth", "m", paper.DEPTH_HOLD, 0.0, display="mm",
                               help="overlap where the ramp stops and the hold begins (the "
                                    "paper's 6 % of the diameter)"))
    noise: float = param(Field("noise", "V", DEFAULT_NOISE_RMS, 0.0, 10.0,
                               help="rms noise at the input"))
    offset: float = param(dataclasses.replace(
        LoadCellChain.specs()["offset"], default=SIM_OFFSET))  # type: ignore[type-var]
    seed: int = param(SEED)
    timing: str = param(TIMING)
    buffer_size: int | None = param(Field("buffer_size", "", None, 1, integer=True,
                                          optional=True, help="acquisition buffer in samples "
                                          "(default: DAQmx's rule)"))
