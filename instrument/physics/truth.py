"""The hidden truth of a simulated rig: the rig file's ``[simulator]`` table, typed.

What the simulators are built from (``gelrig.simulators.twins``) and what a campaign varies:
the sample (sphere sizes, material, where it sits) and the sensors' noise. Protocols never read
it; they find what they need (first touch, touch gap) by contact search. It is the simulated
sample's physics, so it lives here, beside the contact model and below both the rig file
reader (protocols) and the simulators, which each depend on instrument only. Defaults are the
paper's where the paper gives a number (:mod:`.paper`), else the simulated rig's, each
declared once, here; the field specs shared with other
configurations (the MCR 501 simulator's, the ladder fit's) are the module's constants. Light
to import: ``gelrig sim serve`` builds its options from these declarations.

The material is written as ``g_e``, ``nu`` and ``relax = [["20 kPa", "2000 s"], ...]``;
``relax_vertical`` gives F_v its own terms (the paper's anisotropy; shear only).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Self

from gelrig.instrument.core.fields import (
    Choice,
    Config,
    Field,
    Flag,
    Where,
    param,
    read_table,
)
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact_models import UNLOADING_MODELS
from gelrig.instrument.physics.material import Material, RelaxationTerm

#: rms force noise of the simulated compression rig's load cell (N).
FORCE_NOISE = 0.2e-3

SEED = Field("seed", "", 0, 0, 2**31, integer=True, help="seed of the sensor noise")
NU = Field("nu", "", 0.5, 0.0, 0.999, help="Poisson ratio")
R1 = Field("r1", "m", paper.R1_SHEAR, 0.0, 0.05, lo_open=True, display="mm",
           help="radius of the upper sphere (on the arm)")
R2 = Field("r2", "m", paper.R2_SHEAR, 0.0, 0.05, lo_open=True, display="mm",
           help="radius of the lower sphere (fixed)")
UNLOADING = Choice("unloading", UNLOADING_MODELS, "cutoff",
                   help="normal contact on unloading: the paper's cutoff, or MDR "
                        "(physics.md 1b)")
#: The simulated instruments' timing (issue 24, ADR 0242): "ideal" (no drift, no latency)
#: or "documented" (the values the devices' documents give or suggest, UNVERIFIED where
#: marked); a per-field value given beside it overrides the preset's.
TIMING = Choice("timing", ("ideal", "documented"), "ideal",
                help="the simulated instruments' timing: ideal, or the devices' documented "
                     "drift and latencies (ADR 0242)")
CARRY_HISTORY = Flag("carry_history", False,
                     help="keep the hereditary state across separations (a sensitivity "
                          "option; each contact is fresh otherwise, docs/decisions/0140)")

_MATERIAL = {"g_e": Field("g_e", "Pa", None, 0.0, 1e9, lo_open=True), "nu": NU}
_RELAX_G = Field("G", "Pa", None, 0.0, 1e9)
_RELAX_TAU = Field("tau", "s", None, 0.0, 1e9, lo_open=True)
#: Keys of the material, read apart from the fields.
MATERIAL_KEYS = ("g_e", "nu", "relax", "relax_vertical")


def read_material(table: Mapping[str, Any], where: Where, relax_key: str = "relax"
                  ) -> Material | None:
    """G_e, nu and ``relax = [["20 kPa", "2000 s"], ...]`` from a simulator table; None
    when the table gives no material (``g_e``).

    ``relax_key = "relax_vertical"`` reads the terms F_v is computed with (the paper's
    anisotropy: same G_e and nu, its own G_l); None when that key is absent.
    """
    if relax_key != "relax" and relax_key not in table:
        return None
    if "g_e" not in table:
        if relax_key != "relax":
            raise where.error(relax_key, table[relax_key], "needs g_e (and relax) beside it")
        return None
    values = read_table({k: table[k] for k in ("g_e", "nu") if k in table}, _MATERIAL, where)
    raw = table.get(relax_key, [])
    if not isinstance(raw, list):
        raise where.error(relax_key, raw, "a list of [G, tau] pairs")
    terms = []
    for i, pair in enumerate(raw):
        if not (isinstance(pair, list) and len(pair) == 2):
            raise where.error(f"{relax_key}[{i}]", pair, "a pair [G, tau]")
        g = _RELAX_G.parse(pair[0], where.sub(f"{relax_key}[{i}]"))
        tau = _RELAX_TAU.parse(pair[1], where.sub(f"{relax_key}[{i}]"))
        terms.append(RelaxationTerm(g, tau))
    return Material(values["g_e"], tuple(terms), values["nu"])


class _Truth(Config):
    """A ``[simulator]`` table: its fields, and the material written beside them."""

    section: ClassVar[str] = "simulator"
    #: Keys of another rig kind's truth, refused here with a word on why.
    _foreign: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def _materials(cls, table: Mapping[str, Any], where: Where) -> dict[str, Material]:
        material = read_material(table, where)
        return {} if material is None else {"material": material}

    @classmethod
    def from_table(cls, table: Mapping[str, Any], source: str | None = None,
                   section: str | None = None, ignore: Sequence[str] = ()) -> Self:
        """Build from the ``[simulator]`` table: the fields and the material."""
        where = Where(cls.section if section is None else section, source)
        if isinstance(table, Mapping):
            for key in cls._foreign:
                if key in table:
                    raise where.error(key, table[key], "a shear rig's option; not for "
                                      "compression")
        values = read_table(table, cls.specs(), where, ignore=(*ignore, *MATERIAL_KEYS))
        return cls(**values, **cls._materials(table, where))


@dataclass(frozen=True)
class CompressionTruth(_Truth):
    """The hidden truth of the simulated compression rig: the ``[simulator]`` table."""

    _foreign: ClassVar[tuple[str, ...]] = ("relax_vertical", "carry_history")

    sphere_diameter: float = param(Field("sphere_diameter", "m", paper.DIAMETER_COMPRESSION,
                                         0.0, 0.1, lo_open=True, display="mm"))
    first_touch: float = param(Field("first_touch", "m", 6.2e-3, 0.0, 25e-3,
                                     help="stage position where the plate meets the sphere",
                                     display="mm"))
    noise: float = param(Field("noise", "N", FORCE_NOISE, 0.0, 0.1,
                               help="force noise (rms of its white part)"))
    noise_drift: float = param(Field("noise_drift", "N/s", 0.0, -0.01, 0.01,
                                     help="force drift (from the first sample read)"))
    noise_correlated: float = param(Field("noise_correlated", "N", 0.0, 0.0, 0.1,
                                          help="rms of the force noise's correlated part "
                                               "(Ornstein-Uhlenbeck)"))
    noise_tau: float = param(Field("noise_tau", "s", 1.0, 0.0, 1e4, lo_open=True,
                                   help="correlation time of noise_correlated"))
    seed: float = param(SEED)
    unloading: str = param(dataclasses.replace(UNLOADING, help="plate-sphere contact on "
                                               "unloading: the paper's cutoff, or MDR "
                                               "(physics.md 1b)"))
    # How the simulated instruments meet the host's clock (issue 24): ``timing``'s preset
    # (ideal by default, ADR 0242), each field overriding it when given.
    timing: str = param(TIMING)
    daq_drift_ppm: float | None = param(Field(
        "daq_drift_ppm", "", None, -1000.0, 1000.0, optional=True,
        help="the USB-6001's sample clock against the host's, in ppm (spec: +-100, UNVERIFIED;"
             " default: timing's)"))
    daq_latency: float | None = param(Field(
        "daq_latency", "s", None, 0.0, 1.0, optional=True,
        help="USB transfer latency after its last sample (default: timing's)"))
    daq_jitter: float | None = param(Field(
        "daq_jitter", "s", None, 0.0, 1.0, optional=True,
        help="extra latency per transfer, uniform up to this (default: timing's)"))
    daq_transfer: int | None = param(Field(
        "daq_transfer", "", None, 1, 4096, integer=True, optional=True,
        help="samples per USB transfer (default: timing's)"))
    stage_update_period: float = param(Field(
        "stage_update_period", "s", 0.1, 0.0, 10.0, lo_open=True,
        help="KDC101 status update period (APT document: 100 ms)"))
    stage_reply_latency: float | None = param(Field(
        "stage_reply_latency", "s", None, 0.0, 1.0, optional=True,
        help="KDC101 reply and status latency to the host (UNVERIFIED; default: timing's)"))
    # The instruments' hidden facts (issue 30): what the simulated hardware really is,
    # whatever the rig file believes ([stage] counts_per_mm, direction, [force.chain]
    # rated_output are what the drivers use). None: the simulated hardware follows the rig
    # file's belief (its direction and rated output) or the Z825B's nominal scale.
    counts_per_mm: float | None = param(Field(
        "counts_per_mm", "", None, 1e3, 1e6, lo_open=True, optional=True,
        help="the stage's real encoder scale, counts per mm (default: the Z825B's nominal "
             "34554.96)"))
    rated_output: float | None = param(Field(
        "rated_output", "V/V", None, 0.0, 0.01, lo_open=True, optional=True,
        help="the load cell's real rated output (default: the rig file's [force.chain])"))
    direction: int | None = param(Field(
        "direction", "", None, -1, 1, integer=True, optional=True,
        help="where the KDC101's APT 'forward' code really moves: +1 larger counts, -1 "
             "smaller (default: the rig file's [stage] direction)"))
    #: The sphere's material (``g_e``, ``nu``, ``relax``); default the paper's plate fit.
    material: Material = paper.PLATES

    def validate(self, where: Where) -> None:
        _check_direction(self.direction, where)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], source: str | None = None,
                   section: str | None = None, ignore: Sequence[str] = ()) -> Self:
        """As :meth:`_Truth.from_table`; ``direction`` checked as written, with the file."""
        if isinstance(table, Mapping) and table.get("direction") is not None:
            raw = table["direction"]  # None (as stored by to_table): not given
            where = Where(cls.section if section is None else section, source)
            if isinstance(raw, bool) or not isinstance(raw, int | float):
                raise where.error("direction", raw, _DIRECTIONS)
            _check_direction(raw, where)
        return super().from_table(table, source, section, ignore)


_DIRECTIONS = "allowed: +1 (forward is larger counts) or -1 (forward is smaller counts)"


def _check_direction(value: float | None, where: Where) -> None:
    if value is not None and value not in (-1, 1):
        raise where.error("direction", value, _DIRECTIONS)


@dataclass(frozen=True)
class ShearSample(_Truth):
    """The simulated shear sample: the spheres, their material, where the lower one sits
    (hidden: a contact search finds it) and the sensors' noise. The rig file's truth and the
    MCR 501 simulator's configuration both derive from it, so each field is declared once."""

    r1: float = param(R1)
    r2: float = param(R2)
    mu: float = param(Field("mu", "", paper.MU, 0.0, 2.0, help="Coulomb friction coefficient"))
    lower_angle: float = param(Field("lower_angle", "rad", 0.8, -6.3, 6.3,
                                     help="angular position of the lower sphere's centre "
                                          "(hidden)"))
    touch_gap: float = param(Field("touch_gap", "m", 3e-3, 0.0, 0.05, display="mm",
                                   help="gap where the spheres touch on top (hidden)"))
    seed: float = param(SEED)
    unloading: str = param(UNLOADING)
    torque_noise: float = param(Field("torque_noise", "N*m", 1e-7, 0.0, 1e-3,
                                      help="torque noise (standard deviation)"))
    normal_force_noise: float = param(Field("normal_force_noise", "N", 2e-5, 0.0, 0.1,
                                            help="normal force noise (standard deviation)"))
    carry_history: bool = param(CARRY_HISTORY)
    #: The spheres' material (``g_e``, ``nu``, ``relax``); default the paper's F_h fit.
    material: Material = paper.SHEAR_FH
    #: ``relax_vertical``: the material F_v is computed with (the paper's anisotropy); None:
    #: ``material`` for both forces.
    material_vertical: Material | None = None

    @classmethod
    def _materials(cls, table: Mapping[str, Any], where: Where) -> dict[str, Material]:
        out = super()._materials(table, where)
        vertical = read_material(table, where, "relax_vertical")
        if vertical is not None:
            out["material_vertical"] = vertical
        return out


@dataclass(frozen=True)
class ShearTruth(ShearSample):
    """The hidden truth of the simulated shear rig: the ``[simulator]`` table (the sample, and
    how the rheometer simulator is reached)."""

    link: str = param(Choice("link", ("tcp", "direct"), "tcp",
                             help="pyvisa over TCP, or an in-process link"))
