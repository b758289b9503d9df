"""Rig files (TOML): which instruments, over which transport, with which calibration and limits.

Everything is validated on load, before anything connects; errors name the file, the field
(``stage.max_position``), the value and what is allowed. A ``[simulator]`` table gives the
hidden truth of a simulated rig (where the sphere is, its material); it is used only when an
instrument's transport is ``simulator``. The built-in rigs in ``gelrig/rigs/`` are fully
simulated, so gelrig runs on a fresh machine with no hardware.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivers.usb6001.config import Usb6001Config
from instrument.contact import Material, RelaxationTerm
from instrument.errors import ConfigError
from instrument.fields import Field, parse_table, read_toml
from instrument.loadcell import LoadCellChain
from instrument.rheometer import RheometerConfig
from instrument.stage import StageConfig
from protocols.rig import CompressionLimits, ShearLimits

RIG_DIR = Path(__file__).parent / "rigs"
KINDS = ("compression", "shear")

_COMPRESSION_LIMITS = (
    Field("max_force", "N", 2.0, 0.0, 100.0, lo_open=True),
    Field("max_overlap", "m", 2.5e-3, 0.0, 20e-3, lo_open=True),
    Field("fast_speed", "m/s", 1e-3, 0.0, 2.6e-3, lo_open=True),
    Field("acceleration", "m/s^2", 4e-3, 0.0, 10e-3, lo_open=True),
)
_SHEAR_LIMITS = (
    Field("max_torque", "N*m", 5e-3, 0.0, 1.0, lo_open=True),
    Field("max_normal_force", "N", 2.0, 0.0, 100.0, lo_open=True),
    Field("max_overlap", "m", 1.2e-3, 0.0, 10e-3, lo_open=True),
)
_MATERIAL = (
    Field("g_e", "Pa", None, 0.0, 1e9, lo_open=True),
    Field("nu", "", 0.5, 0.0, 0.999),
)
_COMPRESSION_SIM = (
    Field("sphere_diameter", "m", 18.63e-3, 0.0, 0.1, lo_open=True),
    Field("first_touch", "m", 6.2e-3, 0.0, 25e-3),
    Field("noise", "N", 2e-4, 0.0, 0.1),
    Field("seed", "", 0, 0, 2**31, integer=True),
)
_SHEAR_SIM = (
    Field("r1", "m", 9.2e-3, 0.0, 0.05, lo_open=True),
    Field("r2", "m", 9.96e-3, 0.0, 0.05, lo_open=True),
    Field("mu", "", 5e-3, 0.0, 2.0),
    Field("lower_angle", "rad", 0.8, -6.3, 6.3),
    Field("touch_gap", "m", 3e-3, 0.0, 0.05),
    Field("seed", "", 0, 0, 2**31, integer=True),
)
TRANSPORTS = {
    "stage": ("simulator", "serial"),
    "force": ("simulator", "nidaqmx", "grpc"),
    "rheometer": ("simulator", "visa"),
}


@dataclass(frozen=True)
class InstrumentEntry:
    """One instrument table: its transport and address, and its validated configuration."""

    transport: str
    address: str
    config: Any
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def simulated(self) -> bool:
        return self.transport == "simulator"


@dataclass(frozen=True)
class RigSpec:
    """A validated rig file."""

    kind: str
    name: str
    instruments: dict[str, InstrumentEntry]
    limits: CompressionLimits | ShearLimits
    simulator: dict[str, Any]
    table: dict[str, Any]
    source: str

    @property
    def simulated(self) -> bool:
        return all(entry.simulated for entry in self.instruments.values())


def _table(root: dict[str, Any], key: str, source: str, required: bool = True) -> dict[str, Any]:
    value = root.get(key, None if required else {})
    if not isinstance(value, dict):
        raise ConfigError(f"[{key}]", "missing" if value is None else value,
                          "a table is required here", source)
    return value


def _entry(root: dict[str, Any], name: str, source: str) -> tuple[str, str, dict[str, Any]]:
    table = dict(_table(root, name, source))
    transport = table.pop("transport", "simulator")
    allowed = TRANSPORTS[name]
    if transport not in allowed:
        raise ConfigError(f"{name}.transport", transport, f"allowed: {', '.join(allowed)}", source)
    address = table.pop("address", "")
    if not isinstance(address, str):
        raise ConfigError(f"{name}.address", address, "a string (port, URL or resource)", source)
    if transport != "simulator" and transport != "nidaqmx" and not address:
        raise ConfigError(f"{name}.address", "missing", f"required for transport {transport!r}",
                          source)
    return transport, address, table


def material_from(table: dict[str, Any], prefix: str, source: str) -> Material:
    """G_e, nu and ``relax = [["20 kPa", "2000 s"], ...]`` from a simulator table."""
    values = parse_table({k: table[k] for k in ("g_e", "nu") if k in table}, _MATERIAL,
                         prefix, source)
    raw = table.get("relax", [])
    if not isinstance(raw, list):
        raise ConfigError(f"{prefix}relax", raw, "a list of [G, tau] pairs", source)
    terms = []
    for i, pair in enumerate(raw):
        if not (isinstance(pair, list) and len(pair) == 2):
            raise ConfigError(f"{prefix}relax[{i}]", pair, "a pair [G, tau]", source)
        g = Field("G", "Pa", None, 0.0, 1e9).parse(pair[0], f"{prefix}relax[{i}].", source)
        tau = Field("tau", "s", None, 0.0, 1e9, lo_open=True).parse(pair[1],
                                                                   f"{prefix}relax[{i}].", source)
        terms.append(RelaxationTerm(g, tau))
    return Material(values["g_e"], tuple(terms), values["nu"])


def parse_rig(root: dict[str, Any], source: str = "<rig>") -> RigSpec:
    """Validate a rig given as a TOML table."""
    head = _table(root, "rig", source)
    kind = head.get("kind")
    if kind not in KINDS:
        raise ConfigError("rig.kind", kind, f"allowed: {', '.join(KINDS)}", source)
    name = head.get("name", f"{kind} rig")
    if not isinstance(name, str):
        raise ConfigError("rig.name", name, "a string", source)
    expected = {"rig", "limits", "simulator", *(("stage", "force") if kind == "compression"
                                                else ("rheometer",))}
    unknown = sorted(set(root) - expected)
    if unknown:
        raise ConfigError(unknown[0], "?", f"unknown table for a {kind} rig; allowed: "
                          f"{', '.join(sorted(expected))}", source)
    sim_table = _table(root, "simulator", source, required=False)
    limits_table = _table(root, "limits", source, required=False)
    instruments: dict[str, InstrumentEntry] = {}
    simulator: dict[str, Any] = {}
    if kind == "compression":
        transport, address, stage = _entry(root, "stage", source)
        instruments["stage"] = InstrumentEntry(transport, address,
                                               StageConfig.from_mapping(stage, source))
        transport, address, force = _entry(root, "force", source)
        chain = force.pop("chain", {})
        if not isinstance(chain, dict):
            raise ConfigError("force.chain", chain, "a table", source)
        instruments["force"] = InstrumentEntry(
            transport, address, Usb6001Config.from_mapping(force, source),
            {"chain": LoadCellChain.from_mapping(chain, source)})
        limits: CompressionLimits | ShearLimits = CompressionLimits(
            **parse_table(limits_table, _COMPRESSION_LIMITS, "limits.", source))
        rest = {k: v for k, v in sim_table.items() if k not in ("g_e", "nu", "relax")}
        simulator = dict(parse_table(rest, _COMPRESSION_SIM, "simulator.", source))
    else:
        transport, address, rheo = _entry(root, "rheometer", source)
        backend = rheo.pop("backend", "@py")
        instruments["rheometer"] = InstrumentEntry(
            transport, address, RheometerConfig.from_mapping(rheo, source), {"backend": backend})
        limits = ShearLimits(**parse_table(limits_table, _SHEAR_LIMITS, "limits.", source))
        link = sim_table.get("link", "tcp")
        if link not in ("tcp", "direct"):
            raise ConfigError("simulator.link", link, "allowed: tcp, direct", source)
        rest = {k: v for k, v in sim_table.items() if k not in ("g_e", "nu", "relax", "link")}
        simulator = {**parse_table(rest, _SHEAR_SIM, "simulator.", source), "link": link}
    if "g_e" in sim_table:
        simulator["material"] = material_from(sim_table, "simulator.", source)
    if any(math.isnan(v) for v in simulator.values() if isinstance(v, float)):
        raise ConfigError("simulator", "nan", "numbers must be finite", source)
    return RigSpec(kind, name, instruments, limits, simulator, root, source)


def load_rig(path: str | Path) -> RigSpec:
    """Read and validate a rig file."""
    return parse_rig(read_toml(path, "rig file"), str(path))


def default_rig(kind: str) -> Path:
    """The built-in, fully simulated rig of a kind."""
    if kind not in KINDS:
        raise ConfigError("rig", kind, f"allowed: {', '.join(KINDS)}")
    return RIG_DIR / f"{kind}.toml"
