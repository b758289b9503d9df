"""What the composition root hands the GUI: callables and paths, never the factory itself.

gui/ must not import gelrig.* (design.md): the console entry point builds a :class:`Services`
from the rig-file loader, the rig factory, the run metadata and the run-directory naming, and
passes it in. Tests pass their own (a factory wrapper that keeps the rig, say).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from instrument.clock import Clock
from protocols.control import RunControl
from protocols.rehearsal import RehearsalReport
from protocols.rig import Rig
from protocols.rigfile import RigSpec
from protocols.spec import ProtocolSpec


@dataclass(frozen=True)
class Services:
    """Everything the GUI needs from outside gui/.

    ``pace`` is the initial pace of simulated time (``math.inf``: as fast as possible);
    ``analyze`` (optional) turns a finished run directory into a text summary; ``rehearse``
    (optional) runs a protocol on the twin of a rig file and returns the measured figures.
    """

    rig_file: Path
    load_rig: Callable[[Path], RigSpec]
    build_rig: Callable[[RigSpec, Clock], Rig]
    metadata: Callable[[ProtocolSpec, RigSpec, str], Mapping[str, Any]]
    default_run_dir: Callable[[ProtocolSpec], Path]
    pace: float = 1.0
    rig_dir: Path | None = None
    #: where run directories are created (``--runs``): Open run starts there
    runs_dir: Path | None = None
    protocol_dir: Path | None = None
    analyze: Callable[[Path], str] | None = None
    #: the rehearsal of a protocol on the rig's twin (``gelrig plan``), run off the GUI thread
    rehearse: Callable[[ProtocolSpec, RigSpec, RunControl], RehearsalReport] | None = None
