"""``gelrig gui [--rig RIG.toml] [--pace K]``: the Qt application at the rig.

A composition root: it builds the services the GUI needs (rig-file loader, rig factory, run
metadata, run-directory naming) and imports PySide6 only when the command runs, so the rest
of gelrig works without Qt installed.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from instrument.errors import ConfigError, GelrigError

if TYPE_CHECKING:
    from gui.services import Services
    from protocols.control import RunControl
    from protocols.rehearsal import RehearsalReport
    from protocols.rigfile import RigSpec
    from protocols.spec import ProtocolSpec

PACES = {"1": 1.0, "10": 10.0, "100": 100.0, "inf": math.inf, "max": math.inf}


def pace(text: str) -> float:
    """'1', '10x', '100', 'inf' / 'max' (as fast as possible), or any K > 0."""
    key = text.strip().lower()
    try:
        value = PACES[key] if key in PACES else float(key.removesuffix("x"))
    except ValueError:
        value = -1.0
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text!r}: a pace K > 0 (1, 10, 100) or inf")
    return value


def register(sub: argparse._SubParsersAction) -> None:
    gui = sub.add_parser("gui", help="the Qt application at the rig: instruments, manual "
                                     "control, protocols, live plots")
    gui.add_argument("--rig", default=None, metavar="RIG.toml",
                     help="rig file (default: the built-in simulated compression rig)")
    gui.add_argument("--pace", type=pace, default=1.0, metavar="K",
                     help="pace of simulated time: 1, 10, 100 or inf (default 1; ignored on "
                          "hardware, which runs in real time)")
    gui.add_argument("--runs", default=None, metavar="DIR",
                     help="folder for run directories (default: runs/)")
    gui.set_defaults(handler=cmd_gui)


def default_run_dir_parent() -> Path:
    """The folder ``gelrig run`` records into by default (runs/)."""
    return Path("runs")


def make_services(rig_file: Path | None = None, pace: float = 1.0,
                  runs: Path | None = None) -> Services:
    """The GUI's services, wired to gelrig's loader, factory and session metadata."""
    from gelrig.factory import build_rig
    from gelrig.session import default_run_dir, metadata
    from gui.services import Services
    from protocols.rigfile import RIG_DIR, default_rig, load_rig
    from protocols.spec import paper_protocol

    def analysis(path: Path) -> str:
        """``gelrig analyze`` on a run: writes RUN_DIR/analysis, returns its summary."""
        from gelrig.analyze_run import analyze_run

        result = analyze_run(path)
        return f"{result.summary}\n\nreport: {result.report_path}"

    def rehearsal(protocol: ProtocolSpec, spec: RigSpec, control: RunControl
                  ) -> RehearsalReport:
        """``gelrig plan``'s rehearsal: the protocol on the rig's twin, in virtual time."""
        from gelrig.factory import build_twin
        from protocols.rehearsal import rehearse

        twin = build_twin(spec)
        try:
            return rehearse(twin, protocol, control=control)
        finally:
            twin.close()

    def run_dir(protocol: ProtocolSpec) -> Path:
        path = default_run_dir(protocol)
        return runs / path.name if runs is not None else path

    return Services(
        rig_file=rig_file or default_rig("compression"),
        load_rig=load_rig,
        build_rig=build_rig,
        metadata=metadata,
        default_run_dir=run_dir,
        pace=pace,
        rig_dir=RIG_DIR,
        runs_dir=runs if runs is not None else default_run_dir_parent(),
        protocol_dir=paper_protocol("compression").parent,
        analyze=analysis,
        rehearse=rehearsal,
    )


def cmd_gui(args: argparse.Namespace) -> int:
    try:
        from gui.app import run_app
    except ImportError as exc:
        raise GelrigError(f"gelrig gui needs PySide6 and pyqtgraph ({exc}); install them "
                          "with: pip install 'gelrig[gui]'") from None
    rig_file = Path(args.rig) if args.rig else None
    if rig_file is not None and not rig_file.exists():
        raise ConfigError("--rig", str(rig_file), "no such rig file")
    services = make_services(rig_file, args.pace, Path(args.runs) if args.runs else None)
    return run_app(services)
