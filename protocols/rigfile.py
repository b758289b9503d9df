"""Rig files (TOML): which instruments, over which transport, with which calibration and limits.

Everything is validated on load, before anything connects, by the one configuration reader
(:mod:`instrument.fields`); errors name the file, the table and field (``[stage]
max_position``), the value as written and what is allowed. A ``[simulator]`` table gives the
hidden truth of a simulated rig (where the sphere is, its material); it is used only when an
instrument's transport is ``simulator``. The built-in rigs in ``protocols/rigs/`` are fully
simulated, so gelrig runs on a fresh machine with no hardware.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from instrument.contact import Material, RelaxationTerm
from instrument.contact_models import UNLOADING_MODELS
from instrument.daq import Usb6001Config
from instrument.errors import ConfigError
from instrument.fields import Choice, Config, Field, Text, Where, param, read_table, read_toml
from instrument.loadcell import LoadCellChain
from instrument.rheometer import RheometerConfig
from instrument.stage import StageConfig
from protocols.rig import CompressionLimits, ShearLimits

RIG_DIR = Path(__file__).parent / "rigs"
KINDS = ("compression", "shear")
#: pyvisa backends a rheometer entry may name: pyvisa-py, or an installed IVI/NI-VISA library.
VISA_BACKENDS = ("@py", "@ivi")


@dataclass(frozen=True)
class Connection:
    """How an instrument is reached: ``transport`` and its ``address`` (port, URL, resource)."""

    transport: str
    address: str

    @property
    def simulated(self) -> bool:
        return self.transport == "simulator"


@dataclass(frozen=True)
class StageEntry(Connection):
    """The ``[stage]`` table: a KDC101 over a serial port (or the simulator)."""

    config: StageConfig


@dataclass(frozen=True)
class ForceEntry(Connection):
    """The ``[force]`` table: a USB-6001 input (local NI-DAQmx, gRPC, or the simulator)."""

    config: Usb6001Config
    chain: LoadCellChain


@dataclass(frozen=True)
class RheometerEntry(Connection):
    """The ``[rheometer]`` table: an MCR 501 over VISA (or the simulator)."""

    config: RheometerConfig
    backend: str = "@py"


def _material(table: Mapping[str, Any], where: Where, relax_key: str = "relax"
              ) -> Material | None:
    """G_e, nu and ``relax = [["20 kPa", "2000 s"], ...]`` from a simulator table.

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


def _flag(table: Mapping[str, Any], key: str, where: Where) -> bool:
    """A TOML boolean (``key = true``), False when absent."""
    value = table.get(key, False)
    if not isinstance(value, bool):
        raise where.error(key, value, "allowed: true or false")
    return value


_MATERIAL = {"g_e": Field("g_e", "Pa", None, 0.0, 1e9, lo_open=True),
             "nu": Field("nu", "", 0.5, 0.0, 0.999)}
_RELAX_G = Field("G", "Pa", None, 0.0, 1e9)
_RELAX_TAU = Field("tau", "s", None, 0.0, 1e9, lo_open=True)
_MATERIAL_KEYS = ("g_e", "nu", "relax", "relax_vertical", "carry_history")


@dataclass(frozen=True)
class CompressionTruth(Config):
    """The hidden truth of the simulated compression rig: the ``[simulator]`` table."""

    section: ClassVar[str] = "simulator"

    sphere_diameter: float = param(Field("sphere_diameter", "m", 18.63e-3, 0.0, 0.1,
                                         lo_open=True, display="mm"))
    first_touch: float = param(Field("first_touch", "m", 6.2e-3, 0.0, 25e-3,
                                     help="stage position where the plate meets the sphere",
                                     display="mm"))
    noise: float = param(Field("noise", "N", 2e-4, 0.0, 0.1, help="force noise (rms)"))
    seed: float = param(Field("seed", "", 0, 0, 2**31, integer=True))
    unloading: str = param(Choice("unloading", UNLOADING_MODELS, "cutoff",
                                  help="plate-sphere contact on unloading: the paper's cutoff, "
                                       "or MDR (physics.md 1b)"))
    material: Material | None = None


@dataclass(frozen=True)
class ShearTruth(Config):
    """The hidden truth of the simulated shear rig: the ``[simulator]`` table."""

    section: ClassVar[str] = "simulator"

    link: str = param(Choice("link", ("tcp", "direct"), "tcp",
                             help="pyvisa over TCP, or an in-process link"))
    r1: float = param(Field("r1", "m", 9.2e-3, 0.0, 0.05, lo_open=True, display="mm"))
    r2: float = param(Field("r2", "m", 9.96e-3, 0.0, 0.05, lo_open=True, display="mm"))
    mu: float = param(Field("mu", "", 5e-3, 0.0, 2.0, help="Coulomb friction coefficient"))
    lower_angle: float = param(Field("lower_angle", "rad", 0.8, -6.3, 6.3))
    touch_gap: float = param(Field("touch_gap", "m", 3e-3, 0.0, 0.05, display="mm"))
    seed: float = param(Field("seed", "", 0, 0, 2**31, integer=True))
    unloading: str = param(Choice("unloading", UNLOADING_MODELS, "cutoff",
                                  help="normal contact on unloading: the paper's cutoff, or "
                                       "MDR (physics.md 1b)"))
    torque_noise: float = param(Field("torque_noise", "N*m", 1e-7, 0.0, 1e-3,
                                      help="torque noise (standard deviation)"))
    normal_force_noise: float = param(Field("normal_force_noise", "N", 2e-5, 0.0, 0.1,
                                            help="normal force noise (standard deviation)"))
    material: Material | None = None
    #: ``relax_vertical``: the material F_v is computed with (the paper's anisotropy).
    material_vertical: Material | None = None
    #: ``carry_history = true``: keep the hereditary state across separations
    #: (a sensitivity option; each pass is a fresh contact otherwise, docs/decisions/0140).
    carry_history: bool = False


@dataclass(frozen=True)
class CompressionRigSpec:
    """A validated compression rig file."""

    kind: ClassVar[str] = "compression"

    name: str
    stage: StageEntry
    force: ForceEntry
    limits: CompressionLimits
    simulator: CompressionTruth
    table: dict[str, Any]
    source: str

    @property
    def instruments(self) -> dict[str, Connection]:
        return {"stage": self.stage, "force": self.force}

    @property
    def simulated(self) -> bool:
        return self.stage.simulated and self.force.simulated


@dataclass(frozen=True)
class ShearRigSpec:
    """A validated shear rig file."""

    kind: ClassVar[str] = "shear"

    name: str
    rheometer: RheometerEntry
    limits: ShearLimits
    simulator: ShearTruth
    table: dict[str, Any]
    source: str

    @property
    def instruments(self) -> dict[str, Connection]:
        return {"rheometer": self.rheometer}

    @property
    def simulated(self) -> bool:
        return self.rheometer.simulated


RigSpec = CompressionRigSpec | ShearRigSpec

_TRANSPORTS = {
    "stage": ("simulator", "serial"),
    "force": ("simulator", "nidaqmx", "grpc"),
    "rheometer": ("simulator", "visa"),
}


def _table(root: Mapping[str, Any], key: str, source: str, required: bool = True
           ) -> dict[str, Any]:
    value = root.get(key, None if required else {})
    if not isinstance(value, dict):
        raise ConfigError(f"[{key}]", "missing" if value is None else value,
                          "a table is required here", source)
    return dict(value)


def _connection(table: dict[str, Any], name: str, source: str) -> tuple[str, str]:
    """Pop ``transport`` and ``address`` off an instrument table, validated."""
    where = Where(name, source)
    transport = Choice("transport", _TRANSPORTS[name], "simulator").parse(
        table.pop("transport", "simulator"), where)
    address = Text("address", "", "a string (port, URL or resource)", lambda _: True).parse(
        table.pop("address", ""), where)
    if transport not in ("simulator", "nidaqmx") and not address:
        raise where.error("address", "missing", f"required for transport {transport!r}")
    if transport == "grpc":
        _check_grpc(address, where)
    return transport, address


_GRPC = re.compile(r"(?:grpc://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>[^:/]*)",
                   re.IGNORECASE)


def _check_grpc(address: str, where: Where) -> None:
    """A gRPC address is grpc://HOST:PORT with PORT in 1..65535 (checked before connecting)."""
    match = _GRPC.fullmatch(address.strip())
    port = match.group("port") if match else ""
    if not (match and port.isdigit() and 1 <= int(port) <= 65535):
        raise where.error("address", address, "allowed: grpc://HOST:PORT with PORT a number "
                          "1..65535, e.g. grpc://daq-pc:31763")


def _truth(cls: type[CompressionTruth] | type[ShearTruth], table: dict[str, Any], source: str
           ) -> Any:
    where = Where("simulator", source)
    values = read_table(table, cls.specs(), where, ignore=_MATERIAL_KEYS)
    if cls is ShearTruth:
        values["material_vertical"] = _material(table, where, "relax_vertical")
        values["carry_history"] = _flag(table, "carry_history", where)
    else:
        for key in ("relax_vertical", "carry_history"):
            if key in table:
                raise where.error(key, table[key], "a shear rig's option; not for compression")
    return cls(**values, material=_material(table, where))


def parse_rig(root: dict[str, Any], source: str = "<rig>") -> RigSpec:
    """Validate a rig given as a TOML table."""
    head = _table(root, "rig", source)
    kind = Choice("kind", KINDS).parse(head.get("kind"), Where("rig", source))
    name = Text("name", f"{kind} rig").parse(head.get("name", f"{kind} rig"),
                                             Where("rig", source))
    expected = {"rig", "limits", "simulator", *(("stage", "force") if kind == "compression"
                                                else ("rheometer",))}
    unknown = sorted(set(root) - expected)
    if unknown:
        raise ConfigError(f"[{unknown[0]}]", "?", f"unknown table for a {kind} rig; allowed: "
                          f"{', '.join(sorted(expected))}", source)
    sim_table = _table(root, "simulator", source, required=False)
    limits_table = _table(root, "limits", source, required=False)
    if kind == "compression":
        stage = _table(root, "stage", source)
        stage_link = _connection(stage, "stage", source)
        force = _table(root, "force", source)
        force_link = _connection(force, "force", source)
        chain = force.pop("chain", {})
        if not isinstance(chain, dict):
            raise ConfigError("[force.chain]", chain, "a table is required here", source)
        return CompressionRigSpec(
            name,
            StageEntry(*stage_link, StageConfig.from_table(stage, source)),
            ForceEntry(*force_link, Usb6001Config.from_table(force, source),
                       LoadCellChain.from_table(chain, source)),
            CompressionLimits.from_table(limits_table, source),
            _truth(CompressionTruth, sim_table, source), root, source)
    rheo = _table(root, "rheometer", source)
    rheo_link = _connection(rheo, "rheometer", source)
    backend = Choice("backend", VISA_BACKENDS, "@py").parse(rheo.pop("backend", "@py"),
                                                            Where("rheometer", source))
    return ShearRigSpec(
        name,
        RheometerEntry(*rheo_link, RheometerConfig.from_table(rheo, source), backend),
        ShearLimits.from_table(limits_table, source),
        _truth(ShearTruth, sim_table, source), root, source)


def load_rig(path: str | Path) -> RigSpec:
    """Read and validate a rig file."""
    return parse_rig(read_toml(path, "rig file"), str(path))


def default_rig(kind: str) -> Path:
    """The built-in, fully simulated rig of a kind."""
    if kind not in KINDS:
        raise ConfigError("rig", kind, f"allowed: {', '.join(KINDS)}")
    return RIG_DIR / f"{kind}.toml"
