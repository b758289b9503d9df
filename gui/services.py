"""What the composition root hands the GUI: callables and paths, never the factory itself.

gui/ must not import the composition roots (``gelrig.factory``, ``gelrig.cli``,
``gelrig.commands``; design.md): the console entry point builds a :class:`Services` from the
rig-file loader, the rig factory, the analysis and the rehearsal, and passes it in. Runs are
hosted by :class:`gelrig.protocols.host.RunHost` like every front end's. Tests pass their own
services (a factory wrapper that keeps the rig, say).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gelrig.instrument.core.clock import Clock
from gelrig.protocols.control import RunControl
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rehearsal import RehearsalReport
from gelrig.protocols.rig import Rig
from gelrig.protocols.rigfile import RigSpec


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
    pace: float = 1.0
    rig_dir: Path | None = None
    #: where run directories are created (``--runs``): Open run starts there
    runs_dir: Path | None = None
    protocol_dir: Path | None = None
    analyze: Callable[[Path], str] | None = None
    #: the rehearsal of a protocol on the rig's twin (``gelrig plan``), run off the GUI thread
    rehearse: Callable[[Procedure, RigSpec, RunControl], RehearsalReport] | None = None
