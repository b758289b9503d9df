"""Live plots of a run: force against time and plate position (compression); F_h and F_v
against arc travel theta for each pass, overlaid by speed and direction (shear).

Data stay SI; axes carry units and pyqtgraph picks the prefix (mN, mm). Curves redraw from
views of the growing buffers on the window's timer, never per sample block; time curves use
pyqtgraph's peak downsampling and clip-to-view, parametric curves a :class:`PeakDecimator`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QGridLayout, QLabel, QWidget

from gui.cursor import Crosshair
from gui.decimate import PeakDecimator
from gui.rundata import RunData
from instrument.contact import FloatArray

#: Line colours that read well on white (matplotlib's tab10 order).
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#7f7f7f", "#bcbd22")


def colour(k: int) -> str:
    return COLOURS[k % len(COLOURS)]


def configure() -> None:
    """pyqtgraph look for the lab: white background, no antialiasing (fast with many points)."""
    pg.setConfigOptions(background="w", foreground="k", antialias=False)


def _plot(title: str, x: tuple[str, str], y: tuple[str, str]) -> pg.PlotWidget:
    plot = pg.PlotWidget(title=title)
    plot.setLabel("bottom", x[0], units=x[1])
    plot.setLabel("left", y[0], units=y[1])
    plot.showGrid(x=True, y=True, alpha=0.3)
    for side in ("bottom", "left"):  # grid lines at major ticks only: 3x cheaper to paint
        plot.getPlotItem().getAxis(side).setStyle(maxTickLevel=0)
    plot.addLegend(offset=(-10, 10))
    return plot


def _curve(plot: pg.PlotWidget, color: object, name: str | None = None,
           style: Qt.PenStyle = Qt.PenStyle.SolidLine, sorted_x: bool = True
           ) -> pg.PlotDataItem:
    curve = plot.plot(pen=pg.mkPen(color, width=1, style=style), name=name)
    curve.setSkipFiniteCheck(True)
    if sorted_x:  # x increases along the curve: pyqtgraph can downsample and clip
        curve.setDownsampling(auto=True, method="peak")
        curve.setClipToView(True)
    return curve


class LivePlots(QWidget):
    """Base: a grid of plots sharing one cursor readout line."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.grid = QGridLayout(self)
        self.grid.setContentsMargins(0, 0, 0, 0)
        self.readout = QLabel("move the mouse over a plot to read values")
        self.readout.setObjectName("cursorReadout")
        self.plots: list[pg.PlotWidget] = []
        self.cursors: list[Crosshair] = []
        self._version = -1

    def _add(self, plot: pg.PlotWidget, row: int, col: int, x: tuple[str, str],
             y: tuple[str, str]) -> pg.PlotWidget:
        self.grid.addWidget(plot, row, col)
        self.plots.append(plot)
        self.cursors.append(Crosshair(plot, self.readout, x, y))
        return plot

    def refresh(self, data: RunData) -> bool:
        """Redraw what is new; False (and nothing done) if the data did not change."""
        if data.version == self._version:
            return False
        self._version = data.version
        self._draw(data)
        return True

    def _draw(self, data: RunData) -> None:
        raise NotImplementedError

    def paint_now(self) -> None:
        """Paint at once (not later in the event loop), so a redraw's cost can be timed."""
        for plot in self.plots:
            plot.viewport().repaint()

    def clear(self) -> None:
        for plot in self.plots:
            for item in plot.listDataItems():
                plot.removeItem(item)
            legend = plot.getPlotItem().legend
            if legend is not None:
                legend.clear()
        self._version = -1

    def points(self) -> int:
        """Samples held by the curves (before display downsampling)."""
        return sum(0 if c.xData is None else c.xData.size
                   for p in self.plots for c in p.listDataItems())


class CompressionPlots(LivePlots):
    """Force against time and against plate position, one colour per step."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        f, t, z = ("force", "N"), ("time", "s"), ("plate position", "m")
        self.force_t = self._add(_plot("Force against time", t, f), 0, 0, t, f)
        self.force_z = self._add(_plot("Force against plate position", z, f), 0, 1, z, f)
        self.grid.addWidget(self.readout, 1, 0, 1, 2)
        self._t_curves: dict[int, pg.PlotDataItem] = {}
        self._z_curves: dict[int, pg.PlotDataItem] = {}
        self._t_decimators: dict[int, PeakDecimator] = {}
        self._z_decimators: dict[int, PeakDecimator] = {}
        self._drawn: dict[int, int] = {}
        self._samples: dict[int, int] = {}
        self._data: RunData | None = None
        view = self.force_t.getPlotItem().getViewBox()
        view.sigRangeChangedManually.connect(self._view_changed)
        view.sigStateChanged.connect(self._view_changed)
        self._full_view = True

    def clear(self) -> None:
        super().clear()
        self._t_curves.clear()
        self._z_curves.clear()
        self._t_decimators.clear()
        self._z_decimators.clear()
        self._drawn.clear()
        self._samples.clear()
        self._data = None

    def _view_changed(self, *_args: object) -> None:
        """Zoomed in: full-resolution samples (clipped to the view); full view: decimated."""
        full = bool(self.force_t.getPlotItem().getViewBox().autoRangeEnabled()[0])
        if full != self._full_view and self._data is not None:
            self._full_view = full
            self._drawn.clear()
            self._draw(self._data)

    def _draw(self, data: RunData) -> None:
        """Time curves: while the view follows all the data, an incremental peak decimation
        (work per frame in proportion to the new samples, not to millions); zoomed in, the
        samples themselves, which pyqtgraph clips to the view and downsamples."""
        self._data = data
        for step, cols in data.steps():
            t, force = cols.get("t_s"), cols.get("force_N")
            if t is None or force is None or self._drawn.get(step.index) == t.size:
                continue
            if step.index not in self._t_curves:
                color = colour(step.index)
                label = f"{step.index}. {step.name}"
                self._t_curves[step.index] = _curve(self.force_t, color, label)
                self._z_curves[step.index] = _curve(self.force_z, color, label, sorted_x=False)
                self._t_decimators[step.index] = PeakDecimator()
                self._z_decimators[step.index] = PeakDecimator()
            ts, fs = self._t_decimators[step.index].update(t, force)
            if self._full_view:
                self._t_curves[step.index].setData(ts, fs)
            else:
                self._t_curves[step.index].setData(t, force)
            z = cols.get("position_m")
            if z is not None:
                zs, fz = self._z_decimators[step.index].update(z, force)
                self._z_curves[step.index].setData(zs, fz)
            self._drawn[step.index] = t.size
            self._samples[step.index] = t.size

    def points(self) -> int:
        """Samples plotted (the curves may draw fewer: decimated, downsampled, clipped)."""
        return sum(self._samples.values())


@dataclass
class _Pass:
    """One pass of the arm: a contiguous run of rows with the same pass label."""

    label: float
    speed: float
    direction: float
    start: int
    end: int
    f_h: pg.PlotDataItem
    f_v: pg.PlotDataItem


class ShearPlots(LivePlots):
    """F_h and F_v against theta for each pass (colour: speed; line: direction), and the
    torque against time (the contact search has no passes)."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        theta, force = ("arc travel theta", "m"), ("force", "N")
        self.f_h = self._add(_plot("F_h against theta (per pass)", theta, ("F_h", "N")), 0, 0,
                             ("theta", "m"), ("F_h", "N"))
        self.f_v = self._add(_plot("F_v against theta (per pass)", theta, ("F_v", "N")), 0, 1,
                             ("theta", "m"), ("F_v", "N"))
        self.torque_t = self._add(_plot("Torque against time", ("time", "s"),
                                        ("torque", "N*m")), 1, 0, ("time", "s"),
                                  ("torque", "N*m"))
        self.normal_t = self._add(_plot("Normal force against time", ("time", "s"), force), 1, 1,
                                  ("time", "s"), ("normal force", "N"))
        self.f_h.getPlotItem().setTitle("F_h = s M / L against theta (per pass)")
        self.grid.addWidget(self.readout, 2, 0, 1, 2)
        self._passes: dict[int, list[_Pass]] = {}
        self._scanned: dict[int, int] = {}
        self._time_curves: dict[int, tuple[pg.PlotDataItem, pg.PlotDataItem]] = {}
        self._speeds: list[float] = []
        self._named: set[tuple[float, float]] = set()

    def clear(self) -> None:
        super().clear()
        self._passes.clear()
        self._scanned.clear()
        self._time_curves.clear()
        self._speeds.clear()
        self._named.clear()

    def _draw(self, data: RunData) -> None:
        for step, cols in data.steps():
            t = cols.get("t_s")
            if t is None or self._scanned.get(step.index) == t.size:
                continue
            if "torque_Nm" in cols:
                if step.index not in self._time_curves:
                    color = colour(step.index)
                    self._time_curves[step.index] = (
                        _curve(self.torque_t, color, f"{step.index}. {step.name}"),
                        _curve(self.normal_t, color, f"{step.index}. {step.name}"))
                torque, normal = self._time_curves[step.index]
                torque.setData(t, cols["torque_Nm"])
                normal.setData(t, cols["normal_force_N"])
            if "pass" in cols:
                self._scan(step.index, cols)
            self._scanned[step.index] = t.size

    def _scan(self, index: int, cols: dict[str, FloatArray]) -> None:
        labels = cols["pass"]
        n = labels.size
        i = self._scanned.get(index, 0)
        passes = self._passes.setdefault(index, [])
        changed: list[_Pass] = []
        while i < n:
            label = labels[i]
            other = np.flatnonzero(labels[i:n] != label)
            j = i + int(other[0]) if other.size else n
            if passes and passes[-1].end == i and passes[-1].label == label:
                passes[-1].end = j
                changed.append(passes[-1])
            elif label >= 0:
                passes.append(self._new_pass(float(label), float(cols["speed_m_s"][i]),
                                             float(cols["direction"][i]), i, j))
                changed.append(passes[-1])
            i = j
        arm = _arm(cols)
        for p in changed:
            theta = cols["theta_m"][p.start: p.end]
            p.f_h.setData(theta, p.direction * cols["torque_Nm"][p.start: p.end] / arm)
            p.f_v.setData(theta, cols["normal_force_N"][p.start: p.end])

    def _new_pass(self, label: float, speed: float, direction: float, start: int,
                  end: int) -> _Pass:
        if speed not in self._speeds:
            self._speeds.append(speed)
        color = colour(self._speeds.index(speed))
        style = Qt.PenStyle.SolidLine if direction >= 0 else Qt.PenStyle.DashLine
        key = (speed, direction)
        name = None
        if key not in self._named:
            self._named.add(key)
            name = f"{speed:.3g} m/s {'cw' if direction >= 0 else 'ccw'}"
        return _Pass(label, speed, direction, start, end,
                     _curve(self.f_h, color, name, style, sorted_x=False),
                     _curve(self.f_v, color, name, style, sorted_x=False))

    def pass_count(self) -> int:
        return sum(len(p) for p in self._passes.values())


def _arm(cols: dict[str, FloatArray]) -> float:
    """Arm length L (m) from the stream itself: theta = angle * L."""
    angle, theta = cols["angle_rad"], cols["theta_m"]
    ok = np.flatnonzero(np.abs(angle) > 1e-6)
    if ok.size == 0:
        return math.nan
    return float(theta[ok[0]] / angle[ok[0]])


def plots_for(kind: str, parent: QWidget | None = None) -> LivePlots:
    return ShearPlots(parent) if kind == "shear" else CompressionPlots(parent)
