"""Rig files (TOML): which instruments, over which transport, with which calibration and limits.

Everything is validated on load, before anything connects, by the one configuration reader
(:mod:`gelrig.instrument.core.fields`); errors name the file, the table and field (``[stage]
max_position``), the value as written and what is allowed. A ``[simulator]`` table gives the
hidden truth of a simulated rig (where the sphere is, its material;
:mod:`gelrig.instrument.physics.truth`); it is used only when an instrument's transport is
``simulator``. The noise measured at bring-up (``[force.chain] noise``, ``noise_drift``,
``noise_correlated``, ``noise_tau``; ``[rheometer] torque_noise``, ``normal_force_noise``) is
the twin's unless the ``[simulator]`` table gives the same key. The built-in rigs in
``protocols/rigs/`` are fully simulated, so gelrig runs on a fresh machine with no hardware.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from gelrig.instrument.contracts.daq import Usb6001Config
from gelrig.instrument.contracts.loadcell import NOISE_KEYS, LoadCellChain
from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import Choice, Text, Where, read_toml
from gelrig.instrument.physics.truth import CompressionTruth, ShearTruth
from gelrig.protocols.rig import CompressionLimits, ShearLimits

_T = TypeVar("_T", CompressionTruth, ShearTruth)
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
        loadcell = LoadCellChain.from_table(chain, source)
        truth = _learned(CompressionTruth.from_table(sim_table, source), sim_table, loadcell,
                         NOISE_KEYS)
        return CompressionRigSpec(
            name,
            StageEntry(*stage_link, StageConfig.from_table(stage, source)),
            ForceEntry(*force_link, Usb6001Config.from_table(force, source), loadcell),
            CompressionLimits.from_table(limits_table, source), truth, root, source)
    rheo = _table(root, "rheometer", source)
    rheo_link = _connection(rheo, "rheometer", source)
    backend = Choice("backend", VISA_BACKENDS, "@py").parse(rheo.pop("backend", "@py"),
                                                            Where("rheometer", source))
    rheo_config = RheometerConfig.from_table(rheo, source)
    return ShearRigSpec(
        name, RheometerEntry(*rheo_link, rheo_config, backend),
        ShearLimits.from_table(limits_table, source),
        _learned(ShearTruth.from_table(sim_table, source), sim_table, rheo_config,
                 ("torque_noise", "normal_force_noise")), root, source)


def _learned(truth: _T, sim_table: Mapping[str, Any], measured: object,
             keys: tuple[str, ...]) -> _T:
    """The twin learns from bring-up (issue 30): each of ``keys`` measured at the rig (set on
    ``measured``, a rig-file table) is the truth's, unless the ``[simulator]`` table sets it."""
    changes = {k: getattr(measured, k) for k in keys
               if getattr(measured, k) is not None and k not in sim_table}
    return dataclasses.replace(truth, **changes) if changes else truth


def load_rig(path: str | Path) -> RigSpec:
    """Read and validate a rig file."""
    return parse_rig(read_toml(path, "rig file"), str(path))


def default_rig(kind: str) -> Path:
    """The built-in, fully simulated rig of a kind."""
    if kind not in KINDS:
        raise ConfigError("rig", kind, f"allowed: {', '.join(KINDS)}")
    return RIG_DIR / f"{kind}.toml"


__all__ = [
    "KINDS", "RIG_DIR", "VISA_BACKENDS", "CompressionRigSpec", "CompressionTruth", "Connection",
    "ForceEntry", "RheometerEntry", "RigSpec", "ShearRigSpec", "ShearTruth", "StageEntry",
    "default_rig", "load_rig", "parse_rig",
]
