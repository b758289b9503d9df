"""A finished run, opened from its directory: its plots and its analysis summary.

The summary comes from the analysis service when the composition root provides one;
otherwise it is the results the run stored in run.json (fits, first touch, passes).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QFontDatabase
from PySide6.QtWidgets import QMainWindow, QPlainTextEdit, QSplitter, QWidget

from gui.fmt import quantity
from gui.plots import LivePlots, plots_for
from gui.rundata import RunData
from instrument.store import RunDirectory, read_step


def load_run(path: Path) -> tuple[dict[str, Any], RunData]:
    """run.json and every step's samples (also steps a crash interrupted)."""
    run = RunDirectory(path)
    meta = run.read_metadata()
    data = RunData()
    steps = [*meta.get("steps", []),
             *({**s, "name": f"{s['name']} (interrupted)"}
               for s in meta.get("interrupted_steps", []))]
    for key, step in enumerate(steps):
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


def _value(key: str, value: Any) -> str:
    if isinstance(value, float):
        for suffix, unit in (("_m_s", "m/s"), ("_Nm", "N*m"), ("_m", "m"), ("_N", "N"),
                             ("_rad", "rad"), ("_s", "s")):
            if key.endswith(suffix):
                return quantity(value, unit, digits=6)
        return f"{value:.6g}"
    return str(value)


def stored_summary(meta: Mapping[str, Any]) -> str:
    """What the run stored: status, reason, and each step's scalar results and fits."""
    lines = [f"run {meta.get('status', '?')}: {meta.get('reason', '')}",
             f"protocol: {meta.get('protocol_file', '?')}   rig: {meta.get('rig_file', '?')}   "
             f"clock: {meta.get('clock', '?')}"]
    for step in meta.get("steps", []):
        lines.append(f"{step['index']}. {step['name']} [{step.get('kind', '')}]: "
                     f"{step.get('status', '?')}, {step.get('samples', 0)} samples")
        results = step.get("results") or {}
        for key, value in results.items():
            if isinstance(value, int | float | str):
                lines.append(f"     {key} = {_value(key, value)}")
        for fit in results.get("fits", []):
            if "G_e" in fit:
                terms = ", ".join(f"G {r['G']:.0f} Pa, tau {r['tau']:.0f} s"
                                  for r in fit.get("relax", []))
                why = f" -- {fit['not_resolved']}" if fit.get("not_resolved") else ""
                lines.append(f"     fit: G_e {fit['G_e']:.0f} Pa; {terms}{why}")
            elif "error" in fit:
                lines.append(f"     fit failed: {fit['error']}")
        if "passes" in results:
            lines.append(f"     {len(results['passes'])} passes")
    for trip in meta.get("interlock_trips", []):
        lines.append(f"interlock: {trip.get('message', trip)}")
    for fault in meta.get("faults", []):
        lines.append(f"fault: {fault.get('kind')}: {fault.get('message')}")
    return "\n".join(lines)


class RunWindow(QMainWindow):
    """Plots and summary of one run directory (the analysis service's, else run.json's)."""

    _analysis = Signal(str)

    def __init__(self, path: Path, analyze: Callable[[Path], str] | None = None,
                 parent: QWidget | None = None):
        super().__init__(parent)
        self.path = path
        self.meta, self.data = load_run(path)
        self.setWindowTitle(f"gelrig — run {path}")
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
            self._analysis.connect(self._show_analysis, Qt.ConnectionType.QueuedConnection)
            threading.Thread(target=self._analyse, args=(analyze,), daemon=True).start()
        splitter = QSplitter(Qt.Orientation.Vertical)
        splitter.addWidget(self.plots)
        splitter.addWidget(self.summary)
        splitter.setSizes([600, 200])
        self.setCentralWidget(splitter)
        self.resize(1100, 800)

    def _analyse(self, analyze: Callable[[Path], str]) -> None:
        try:
            text = analyze(self.path)
        except Exception as exc:  # show the stored results rather than nothing
            text = f"analysis failed ({type(exc).__name__}: {exc}); stored results:\n" \
                   f"{self.stored}"
        with contextlib.suppress(RuntimeError):  # the window may be gone
            self._analysis.emit(text)

    def _show_analysis(self, text: str) -> None:
        self.summary.setPlainText(text)
        self.analysed = True
