"""The live relaxation fit of a hold, in the GUI: G(t) with the running fit and its band, and
the fit's history (tau and its relative uncertainty against hold time).

Fed by :class:`gelrig.protocols.events.FitUpdate` events (a few dozen a hold); each redraws at once
(a few hundred points). Time runs from the hold's start.
"""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QGridLayout, QLabel, QWidget

from gelrig.gui.plots import colour, time_plot
from gelrig.protocols.events import FitUpdate, StepStarted

#: Band drawn around the fitted curve, in standard deviations (about 95 %).
BAND = 2.0


def summary(event: FitUpdate) -> str:
    """One line for people: ``tau_1 1413 s +- 1.7 % (forecast at end 0.31 %), 1 term
    resolved``; what the CLI's progress line says."""
    st = event.state
    parts = []
    for k, r in enumerate(st.relax, 1):
        rel = st.relative.get(f"tau_{k}", math.nan)
        fc = st.forecast.get(f"tau_{k}", math.nan)
        shown = f"{rel * 100:.2g} %" if math.isfinite(rel) else "undetermined"
        end = f" (forecast at end {fc * 100:.2g} %)" if math.isfinite(fc) else ""
        parts.append(f"tau_{k} {r.tau:.4g} s +- {shown}{end}")
    resolved = f"{st.terms_resolved} term{'s' if st.terms_resolved != 1 else ''} resolved"
    met = "; target met" if event.met else ""
    return f"at {st.elapsed:.0f} s: {'; '.join(parts)}; {resolved}{met}"


class FitPanel(QWidget):
    """G(t) of the hold with the live fit and its band (top), tau and its relative standard
    error against hold time (bottom), and the latest fit as a line."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        grid = QGridLayout(self)
        grid.setContentsMargins(0, 0, 0, 0)
        # hold time in s, min or h by the span shown (never ks)
        self.g_plot = time_plot("G(t) during the hold, live fit and 2 s.d. band", "hold time")
        self.g_plot.setLabel("left", "G", units="Pa")
        self.tau_plot = time_plot("Live fit history: tau (left), relative s.e. (right, %)",
                                  "hold time")
        self.tau_plot.setLabel("left", "tau (s)")
        self.rel_plot = time_plot(None, "hold time")
        self.rel_plot.setLabel("left", "relative s.e. of tau (%)")
        self.rel_plot.setLogMode(y=True)
        for plot in (self.g_plot, self.tau_plot, self.rel_plot):
            plot.showGrid(x=True, y=True, alpha=0.3)
            plot.setMinimumSize(120, 90)
        self.tau_plot.getPlotItem().getAxis("left").enableAutoSIPrefix(False)
        self.line = QLabel("no hold yet: the live fit starts once a ramp_hold holds")
        self.line.setObjectName("liveFitLine")
        self.line.setWordWrap(True)
        grid.addWidget(self.g_plot, 0, 0, 1, 2)
        grid.addWidget(self.tau_plot, 1, 0)
        grid.addWidget(self.rel_plot, 1, 1)
        grid.addWidget(self.line, 2, 0, 1, 2)
        grid.setRowStretch(0, 3)
        grid.setRowStretch(1, 2)
        self.points_item = self.g_plot.plot(pen=None, symbol="o", symbolSize=3,
                                     symbolPen=None, symbolBrush="#7f7f7f")
        self.fit_curve = self.g_plot.plot(pen=pg.mkPen(colour(3), width=2))
        self.band_hi = self.g_plot.plot(pen=pg.mkPen(colour(3), width=1, style=Qt.PenStyle.DotLine))
        self.band_lo = self.g_plot.plot(pen=pg.mkPen(colour(3), width=1, style=Qt.PenStyle.DotLine))
        self.fill = pg.FillBetweenItem(self.band_hi, self.band_lo,
                                       brush=pg.mkBrush(214, 39, 40, 50))
        self.g_plot.addItem(self.fill)
        self.taus: list[pg.PlotDataItem] = []
        self.rels: list[pg.PlotDataItem] = []
        self.history: list[FitUpdate] = []
        self.stop = pg.InfiniteLine(angle=90, pen=pg.mkPen("r"))
        self.stop.setVisible(False)
        self.tau_plot.addItem(self.stop)

    def clear(self) -> None:
        """Forget the hold shown (a new ramp_hold starts)."""
        self.history.clear()
        for item in (self.points_item, self.fit_curve, self.band_hi, self.band_lo):
            item.setData([], [])
        for item in (*self.taus, *self.rels):
            item.setData([], [])
        self.stop.setVisible(False)
        self.line.setText("live fit: waiting for the first refit of the hold")

    def on_event(self, event: object) -> None:
        """Take a run event: a ramp_hold's start clears, a :class:`FitUpdate` redraws."""
        if isinstance(event, StepStarted) and event.kind == "ramp_hold":
            self.clear()
        elif isinstance(event, FitUpdate):
            self.show_fit(event)

    def show_fit(self, event: FitUpdate) -> None:
        if self.history and event.index != self.history[-1].index:
            self.clear()
        self.history.append(event)
        st = event.state
        self.points_item.setData(*st.data)
        t, g, sd = st.curve
        self.fit_curve.setData(t, g)
        ok = np.isfinite(sd)
        if ok.all():
            self.band_hi.setData(t, g + BAND * sd)
            self.band_lo.setData(t, g - BAND * sd)
        else:
            self.band_hi.setData([], [])
            self.band_lo.setData([], [])
        terms = max(len(e.state.relax) for e in self.history)
        while len(self.taus) < terms:
            k = len(self.taus)
            self.taus.append(self.tau_plot.plot(pen=pg.mkPen(colour(k), width=1), symbol="o",
                                                symbolSize=4, symbolBrush=colour(k),
                                                name=f"tau_{k + 1}"))
            self.rels.append(self.rel_plot.plot(pen=pg.mkPen(colour(k), width=1), symbol="o",
                                                symbolSize=4, symbolBrush=colour(k)))
        for k in range(terms):
            pts = [(e.state.elapsed, e.state.relax[k].tau,
                    e.state.relative.get(f"tau_{k + 1}", math.nan))
                   for e in self.history if len(e.state.relax) > k]
            x, tau, rel = (np.array(v, dtype=float) for v in zip(*pts, strict=True)) \
                if pts else (np.empty(0),) * 3
            self.taus[k].setData(x, tau)
            good = np.isfinite(rel) & (rel > 0)
            self.rels[k].setData(x[good], 100 * rel[good])
        if event.ending:
            self.stop.setPos(st.elapsed)
            self.stop.setVisible(True)
        self.line.setText(("adaptive hold ends: " if event.ending else "live fit ")
                          + summary(event))

    def points(self) -> int:
        """Refits shown."""
        return len(self.history)
