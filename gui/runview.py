"""A finished run, opened from its directory: its plots and its analysis summary.

The summary comes from the analysis service when the composition root provides one;
otherwise it is the results the run stored in run.json (fits, first touch, passes).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QCloseEvent, QFontDatabase
from PySide6.QtWidgets import QApplication, QMainWindow, QPlainTextEdit, QSplitter, QWidget

from gelrig.gui import offthread
from gelrig.gui.fmt import quantity
from gelrig.gui.plots import LivePlots, plots_for
from gelrig.gui.rundata import RunData
from gelrig.instrument.core.store import RunDirectory, read_step


def load_run(path: Path) -> tuple[dict[str, Any], RunData]:
    """run.json and every step's samples (also steps a crash interrupted)."""
    run = RunDirectory(path)
    meta = run.read_metadata()
    data = RunData()
    steps = [*meta.get("steps", []),
             *({**s, "name": f"{s['name']} (interrupted)"}
               for s in meta.get("interrupted_steps", []))]
    for key, step in enumerate(steps):  # the stored index, as in run.json and the file names
        key = int(step.get("index", key))
        file = run.path / step["file"]
        if not file.exists():
            continue
        cols = read_step(file)
        data.begin_step(key, step["name"], step.get("kind", ""), dict.fromkeys(cols, ""))
        data.append(key, cols)
        data.finish_step(key, step.get("status", "?"), step.get("results") or {})
    return meta, data


def rig_kind(meta: Mapping[str, Any]) -> str:
    protocol = meta.get("protocol", {})
    head = protocol.get("protocol", {}) if isinstance(protocol, dict) else {}
    return str(head.get("rig", "compression"))


#: A stored result's name suffix -> its SI unit.
_SUFFIXES = (("_m_s", "m/s"), ("_Pa", "Pa"), ("_Nm", "N*m"), ("_m", "m"), ("_N", "N"),
             ("_rad", "rad"), ("_s", "s"))


def _value(key: str, value: Any) -> str:
    if isinstance(value, float):
        for suffix, unit in _SUFFIXES:
            if key.endswith(suffix):
                return quantity(value, unit, digits=6)
        return f"{value:.6g}"
    return str(value)


def _name(key: str, value: Any) -> str:
    """A stored name as people read it beside its value in lab units: 'measured_depth_m'
    -> 'measured depth' (the unit is on the value, not an SI suffix left on the name)."""
    if isinstance(value, float):
        for suffix, _unit in _SUFFIXES:
            if key.endswith(suffix):
                key = key.removesuffix(suffix)
                break
    return key.replace("_", " ")


def _fit_line(fit: Mapping[str, Any], position: int) -> str:
    """A stored fit as one line (ADR 0261): ``N-term fit: G_e ..., G_1 ..., tau_1 ...`` when
    every term it asked for is resolved, else ``N-term fit: not resolved: <reason>`` and no
    values (a 2-term entry that holds the resolved 1-term values is not a 2-term result).
    ``position``: the fit's place in the hold's list (1: the 1-term fit), its term count
    when run.json does not say."""
    relax = list(fit.get("relax") or [])
    requested = int(fit.get("terms_requested", position))
    if "error" in fit:
        return f"{requested}-term fit failed: {fit['error']}"
    resolved = fit.get("resolved")
    if not isinstance(resolved, bool):
        counted = fit.get("terms_resolved")
        resolved = (isinstance(counted, int) and counted >= requested
                    and not fit.get("not_resolved"))
    if not resolved or len(relax) != requested:
        why = fit.get("not_resolved") or "not every term is resolved"
        return f"{requested}-term fit: not resolved: {why}"
    terms = "".join(f", G_{k} {quantity(float(r['G']), 'Pa', 3)}, "
                    f"tau_{k} {quantity(float(r['tau']), 's', 4)}"
                    for k, r in enumerate(relax, start=1))
    return f"{requested}-term fit: G_e {quantity(float(fit['G_e']), 'Pa', 3)}{terms}"


def step_lines(results: Mapping[str, Any]) -> list[str]:
    """A step's stored results as lines a scientist reads: first touch +- spread, scalars
    with units, fits, the number of passes (shown when the step completes and in Open run)."""
    lines = []
    if isinstance(results.get("first_touch_m"), float):
        touch = f"first touch {quantity(results['first_touch_m'], 'm', 6)}"
        spread = results.get("first_touch_spread_m")
        if isinstance(spread, float):
            touch += f" (spread {quantity(spread, 'm', 3)})"
        lines.append(touch)
    for key, value in results.items():
        if key in ("first_touch_m", "first_touch_spread_m"):
            continue
        if isinstance(value, int | float | str):
            lines.append(f"{_name(key, value)} = {_value(key, value)}")
    for position, fit in enumerate(results.get("fits", []), start=1):
        if isinstance(fit, Mapping) and ("G_e" in fit or "error" in fit):
            lines.append(_fit_line(fit, position))
    if "passes" in results:
        lines.append(f"{len(results['passes'])} passes")
    return lines


def stored_summary(meta: Mapping[str, Any]) -> str:
    """What the run stored: status, reason, and each step's scalar results and fits."""
    lines = [f"run {meta.get('status', '?')}: {meta.get('reason', '')}",
             f"protocol: {meta.get('protocol_file', '?')}   rig: {meta.get('rig_file', '?')}   "
             f"clock: {meta.get('clock', '?')}"]
    for step in meta.get("steps", []):
        lines.append(f"step {step['index']}. {step['name']} [{step.get('kind', '')}]: "
                     f"{step.get('status', '?')}, {step.get('samples', 0)} samples")
        lines.extend(f"     {line}" for line in step_lines(step.get("results") or {}))
    for trip in meta.get("interlock_trips", []):
        lines.append(f"interlock: {trip.get('message', trip)}")
    for fault in meta.get("faults", []):
        lines.append(f"fault: {fault.get('kind')}: {fault.get('message')}")
    return "\n".join(lines)


#: The Open run window's preferred size (px); never larger than the screen's available area.
RUN_WINDOW_SIZE = (1100, 800)


def fit_to_screen(window: QWidget, preferred: tuple[int, int]) -> None:
    """Size ``window`` to ``preferred`` within the available screen area (the window frame
    allowed for), and place it at the area's top left; it stays resizable."""
    screen = window.screen() or QApplication.primaryScreen()
    if screen is None:
        window.resize(*preferred)
        return
    area = screen.availableGeometry()
    frame_w, frame_h = 8, 32  # a typical title bar and border, before the frame is known
    width = min(preferred[0], area.width() - frame_w)
    height = min(preferred[1], area.height() - frame_h)
    window.resize(max(width, 200), max(height, 150))
    window.move(area.topLeft())


class RunWindow(QMainWindow):
    """Plots and summary of one run directory (the analysis service's, else run.json's)."""

    def __init__(self, path: Path, analyze: Callable[[Path], str] | None = None,
                 parent: QWidget | None = None):
        super().__init__(parent)
        self.path = path
        self.meta, self.data = load_run(path)
        self.setWindowTitle(f"gelrig — run {path.name} ({self.meta.get('status', '?')})")
        self.plots: LivePlots = plots_for(rig_kind(self.meta))
        self.plots.refresh(self.data)
        self.summary = QPlainTextEdit()
        self.summary.setReadOnly(True)
        self.summary.setFont(QFontDatabase.systemFont(QFontDatabase.SystemFont.FixedFont))
        self.stored = stored_summary(self.meta)
        self.summary.setPlainText(self.stored)
        self.analysed = analyze is None
        if analyze is not None:  # fits can take seconds: off the GUI thread
            self.summary.setPlainText(f"analysing…\n\nstored results:\n{self.stored}")
            path, stored = self.path, self.stored

            def work() -> str:
                try:
                    return analyze(path)
                except Exception as exc:  # show the stored results rather than nothing
                    return f"analysis failed ({type(exc).__name__}: {exc}); stored " \
                           f"results:\n{stored}"

            offthread.start(work, self._show_analysis, name="gelrig-analysis")
        splitter = QSplitter(Qt.Orientation.Vertical)
        splitter.addWidget(self.plots)
        splitter.addWidget(self.summary)
        splitter.setSizes([600, 200])
        for widget in (self.plots, self.summary):
            widget.setMinimumSize(0, 0)  # the window may shrink to a small screen
        self.setCentralWidget(splitter)
        fit_to_screen(self, RUN_WINDOW_SIZE)

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt override)
        """Let go of the run's samples and curves at once (an analysis thread may still
        hold the window for a while)."""
        self.plots.clear()
        self.data = RunData()
        event.accept()

    def _show_analysis(self, text: str) -> None:
        self.summary.setPlainText(text)
        self.analysed = True
