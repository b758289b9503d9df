"""``gelrig gui [--rig RIG.toml] [--pace K]``: the Qt application at the rig.

A composition root: it builds the services the GUI needs (rig-file loader, rig factory, run
metadata, run-directory naming) and imports PySide6 only when the command runs, so the rest
of gelrig works without Qt installed.
"""

from __future__ import annotations

import argparse
import ctypes.util
import math
import os
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from gelrig.instrument.core.errors import ConfigError, GelrigError

if TYPE_CHECKING:
    from gelrig.gui.services import Services
    from gelrig.protocols.control import RunControl
    from gelrig.protocols.procedure import Procedure
    from gelrig.protocols.rehearsal import RehearsalReport
    from gelrig.protocols.rigfile import RigSpec

PACES = {"1": 1.0, "10": 10.0, "100": 100.0, "inf": math.inf, "max": math.inf}

#: Shared libraries Qt's xcb platform plugin (PySide6 6.11) loads, and the Debian package of
#: each (found with ldd on libqxcb.so, libQt6XcbQpa, libQt6Gui and libQt6Widgets).
XCB_LIBRARIES: tuple[tuple[str, str], ...] = (
    ("xcb-cursor", "libxcb-cursor0"), ("xcb-icccm", "libxcb-icccm4"),
    ("xcb-keysyms", "libxcb-keysyms1"), ("xcb-image", "libxcb-image0"),
    ("xcb-render-util", "libxcb-render-util0"), ("xcb-randr", "libxcb-randr0"),
    ("xcb-shape", "libxcb-shape0"), ("xcb-xfixes", "libxcb-xfixes0"),
    ("xcb-sync", "libxcb-sync1"), ("xcb-shm", "libxcb-shm0"), ("xcb-xkb", "libxcb-xkb1"),
    ("xcb-util", "libxcb-util1"), ("X11-xcb", "libx11-xcb1"),
    ("xkbcommon-x11", "libxkbcommon-x11-0"), ("xkbcommon", "libxkbcommon0"),
    ("EGL", "libegl1"), ("GL", "libgl1"), ("fontconfig", "libfontconfig1"),
    ("dbus-1", "libdbus-1-3"), ("glib-2.0", "libglib2.0-0"),
)


def missing_libraries(env: Mapping[str, str],
                      find: Callable[[str], str | None] | None = None,
                      platform: str | None = None) -> list[str]:
    """Debian packages whose libraries the Qt window needs and this machine lacks (checked
    before Qt starts, so the user gets their names, not Qt's plugin error). Only for the
    xcb platform (Linux, QT_QPA_PLATFORM unset or xcb); offscreen and others need none."""
    find = find or ctypes.util.find_library
    platform = platform or sys.platform
    qpa = env.get("QT_QPA_PLATFORM", "").split(":", 1)[0]
    wayland = not qpa and env.get("WAYLAND_DISPLAY") and not env.get("DISPLAY")
    if not platform.startswith("linux") or qpa not in ("", "xcb") or wayland:
        return []
    return [package for library, package in XCB_LIBRARIES if find(library) is None]


def check_display(env: Mapping[str, str], find: Callable[[str], str | None] | None = None,
                  platform: str | None = None) -> None:
    """Raise a one-line ConfigError if the window cannot open: missing system libraries
    (with the apt-get line that installs them) or no X display."""
    platform = platform or sys.platform
    missing = missing_libraries(env, find, platform)
    if missing:
        raise ConfigError("system libraries", ", ".join(missing),
                          f"the Qt window needs them: sudo apt-get install {' '.join(missing)}")
    qpa = env.get("QT_QPA_PLATFORM", "").split(":", 1)[0]
    if (platform.startswith("linux") and qpa in ("", "xcb") and not env.get("DISPLAY")
            and not env.get("WAYLAND_DISPLAY")):
        raise ConfigError("DISPLAY", "", "no display to open the window on: run it in a "
                          "desktop session, or under xvfb-run, or set QT_QPA_PLATFORM=offscreen")


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
    from gelrig.gui.services import Services
    from gelrig.protocols.rigfile import RIG_DIR, default_rig, load_rig
    from gelrig.protocols.spec import paper_protocol

    def analysis(path: Path) -> str:
        """``gelrig analyze`` on a run: writes RUN_DIR/analysis, returns its summary."""
        from gelrig.analyze_run import analyze_run

        result = analyze_run(path)
        return f"{result.summary}\n\nreport: {result.report_path}"

    def rehearsal(protocol: Procedure, spec: RigSpec, control: RunControl
                  ) -> RehearsalReport:
        """``gelrig plan``'s rehearsal: the protocol on the rig's twin, in virtual time."""
        from gelrig.factory import build_twin
        from gelrig.protocols.rehearsal import rehearse

        twin = build_twin(spec)
        try:
            return rehearse(twin, protocol, control=control)
        finally:
            twin.close()

    return Services(
        rig_file=rig_file or default_rig("compression"),
        load_rig=load_rig,
        build_rig=build_rig,
        pace=pace,
        rig_dir=RIG_DIR,
        runs_dir=runs if runs is not None else default_run_dir_parent(),
        protocol_dir=paper_protocol("compression").parent,
        analyze=analysis,
        rehearse=rehearsal,
    )


def cmd_gui(args: argparse.Namespace) -> int:
    rig_file = Path(args.rig) if args.rig else None
    if rig_file is not None and not rig_file.exists():
        raise ConfigError("--rig", str(rig_file), "no such rig file")
    check_display(os.environ)  # before Qt loads: its own error names no package
    try:
        from gelrig.gui.app import run_app
    except ImportError as exc:
        raise GelrigError(f"gelrig gui needs PySide6 and pyqtgraph ({exc}); install them "
                          "with: pip install 'gelrig[gui]'") from None
    services = make_services(rig_file, args.pace, Path(args.runs) if args.runs else None)
    return run_app(services)
