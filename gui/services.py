"""What the composition root hands the GUI: callables and paths, never the factory itself.

gui/ must not import gelrig.* (design.md): the console entry point builds a :class:`Services`
from the rig-file loader, the rig factory, the run metadata and the run-directory naming, and
passes it in. Tests pass their own (a factory wrapper that keeps the rig, say).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from instrument.clock import Clock
from protocols.rig import CompressionLimits, Rig, ShearLimits
from protocols.spec import ProtocolSpec


class RigSpecLike(Protocol):
    """The parts of a validated rig file the GUI reads (gelrig.rigfile.RigSpec meets it)."""

    @property
    def kind(self) -> str: ...

    @property
    def name(self) -> str: ...

    @property
    def source(self) -> str: ...

    @property
    def simulated(self) -> bool: ...

    @property
    def limits(self) -> CompressionLimits | ShearLimits: ...


@dataclass(frozen=True)
class Services:
    """Everything the GUI needs from outside gui/.

    ``pace`` is the initial pace of simulated time (``math.inf``: as fast as possible);
    ``analyze`` (optional) turns a finished run directory into a text summary.
    """

    rig_file: Path
    load_rig: Callable[[Path], RigSpecLike]
    build_rig: Callable[[RigSpecLike, Clock], Rig]
    metadata: Callable[[ProtocolSpec, RigSpecLike, str], Mapping[str, Any]]
    default_run_dir: Callable[[ProtocolSpec], Path]
    pace: float = 1.0
    rig_dir: Path | None = None
    protocol_dir: Path | None = None
    analyze: Callable[[Path], str] | None = None
