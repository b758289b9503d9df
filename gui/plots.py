"""Live plots of a run: force against time and plate position (compression); F_h and F_v
against arc travel theta for each pass, overlaid by speed and direction (shear).

Data stay SI; axes carry units: force gets pyqtgraph's prefix (mN), while lengths, torque and
speeds show in the lab's fixed units (plate position and theta in mm, torque in mN*m, speeds
in um/s) by an axis scale. Time runs from the run's first sample (a curve is shifted, its data
untouched). Step labels use the run's step index (as in run.json and the step files). Legends
sit beside the plots, never over the curves. Curves redraw from views of the growing buffers
on the window's timer, never per sample block; time curves use pyqtgraph's peak downsampling
and clip-to-view, parametric curves a :class:`PeakDecimator`.
"""

from __future__ import annotations

import html
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QComboBox, QGridLayout, QHBoxLayout, QLabel, QWidget

from gelrig.gui.cursor import Crosshair
from gelrig.gui.decimate import PeakDecimator
from gelrig.gui.rundata import RunData
from gelrig.instrument.physics.contact import FloatArray

#: Line colours that read well on white (matplotlib's tab10 order).
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#7f7f7f", "#bcbd22")


#: Step colours of the shear time plots, apart from the first speeds' colours (no confusion
#: in the shared legend).
STEP_COLOURS = ("#555555", "#8c564b", "#e377c2", "#17becf", "#bcbd22")


def colour(k: int) -> str:
    return COLOURS[k % len(COLOURS)]


def configure() -> None:
    """pyqtgraph look for the lab: white background, no antialiasing (fast with many points)."""
    pg.setConfigOptions(background="w", foreground="k", antialias=False)


#: Fixed display units of SI quantities: SI unit -> (display unit, factor).
DISPLAY = {"m": ("mm", 1e3), "N*m": ("mN*m", 1e3), "m/s": ("µm/s", 1e6)}


#: Time axis units by the span shown: (unit, seconds per unit, used below this span in s).
TIME_UNITS = (("s", 1.0, 600.0), ("min", 60.0, 3 * 3600.0), ("h", 3600.0, math.inf))


class TimeAxis(pg.AxisItem):
    """A time axis (data in s) in s, min or h, chosen by the span shown (never "ks"): up to
    10 min in s, up to 3 h in min, beyond in h; ticks fall on round values of that unit."""

    name = "time"
    unit = ""  # none chosen yet
    _made = False  # pyqtgraph sets a range while it makes the axis: chosen once made

    def __init__(self, name: str, orientation: str = "bottom", **kwargs: Any):
        super().__init__(orientation, **kwargs)
        self.name, self._made = name, True
        self.enableAutoSIPrefix(False)
        self._choose(*self.range)

    def setRange(self, mn: float, mx: float) -> None:  # noqa: N802 (pyqtgraph's name)
        if self._made:
            self._choose(mn, mx)
        super().setRange(mn, mx)

    def _choose(self, mn: float, mx: float) -> None:
        span = abs(mx - mn) if math.isfinite(mx - mn) else 0.0
        unit, per = next((u, f) for u, f, below in TIME_UNITS if span < below)
        if unit != self.unit:  # only on a change: the label's size never feeds back
            self.unit = unit
            self.setScale(1.0 / per)
            self.setLabel(f"{self.name} ({unit})")


def time_plot(title: str | None = None, name: str = "time") -> pg.PlotWidget:
    """A plot whose bottom axis is a :class:`TimeAxis`."""
    return pg.PlotWidget(title=title, axisItems={"bottom": TimeAxis(name)})


def _axis(plot: pg.PlotWidget, side: str, name: str, unit: str) -> None:
    """Label an axis; SI data shown in the fixed display unit of :data:`DISPLAY` if any,
    else with pyqtgraph's automatic prefix; time in s, min or h (:class:`TimeAxis`)."""
    axis = plot.getPlotItem().getAxis(side)
    if isinstance(axis, TimeAxis):
        pass  # labelled by the span it shows
    elif unit in DISPLAY:
        shown, factor = DISPLAY[unit]
        axis.enableAutoSIPrefix(False)
        axis.setScale(factor)
        plot.setLabel(side, f"{name} ({shown})")
    else:
        plot.setLabel(side, name, units=unit)
    axis.setStyle(maxTickLevel=0)  # grid lines at major ticks only: 3x cheaper to paint


def make_plot(title: str, x: tuple[str, str], y: tuple[str, str]) -> pg.PlotWidget:
    """A plot of ``y`` against ``x`` (each (name, SI unit)), shown in the lab's units."""
    plot = time_plot(title, x[0]) if x[1] == "s" else pg.PlotWidget(title=title)
    _axis(plot, "bottom", *x)
    _axis(plot, "left", *y)
    plot.showGrid(x=True, y=True, alpha=0.3)
    item = plot.getPlotItem()
    item.layout.setContentsMargins(2, 2, 24, 2)  # room for the last tick label at the right
    plot.setMinimumSize(120, 90)
    return plot


def speed_text(speed: float) -> str:
    """A sliding speed (m/s) as the lab reads it: '119 µm/s'."""
    shown, factor = DISPLAY["m/s"]
    return f"{speed * factor:.3g} {shown}"


def legend_html(entries: list[tuple[str, Qt.PenStyle, str]]) -> str:
    """A legend as rich text: a coloured line sample (solid or dashed) and its label."""
    parts = []
    for color, style, label in entries:
        sample = "━━" if style == Qt.PenStyle.SolidLine else "╍╍"
        parts.append(f"<span style='color:{color}; font-weight:bold'>{sample}</span>&nbsp;"
                     f"{html.escape(label)}")
    return "&nbsp;&nbsp;&nbsp; ".join(parts)


def _shift(curve: pg.PlotDataItem, data: RunData) -> None:
    """Show a time curve from the run's first sample (its data stay on the run's clock)."""
    x = -(data.t0 if data.t0 is not None else 0.0)
    if curve.pos().x() != x:
        curve.setPos(x, 0)


class Curve(pg.PlotDataItem):
    """A curve whose auto-range bounds are those of all its data, never of what is drawn.

    pyqtgraph's own bounds come from the displayed data, which auto-downsampling picks by
    the view's width: the range set from them changes the downsampling, which changes the
    bounds, which changes the range... With x not increasing (a new rig clock), or a
    factor near a whole number, that never settles and the window repaints for ever
    (issue 25: no timer, no click, no STOP served). Bounds of the data break the cycle."""

    def __init__(self, *args: object, **kwargs: object):
        self._bounds: dict[int, tuple[float, float] | tuple[None, None]] = {}
        super().__init__(*args, **kwargs)

    def setData(self, *args: object, **kwargs: object) -> None:  # noqa: N802 (Qt's name)
        self._bounds = {}
        super().setData(*args, **kwargs)

    def dataBounds(self, ax: int, frac: float = 1.0,  # noqa: N802 (pyqtgraph's name)
                   orthoRange: object = None) -> tuple[float, float] | tuple[None, None]:
        """(min, max) of the finite data along ``ax`` (0: x, 1: y); (None, None) if none.
        ``frac`` and ``orthoRange`` are not used: the view never asks for them here."""
        if ax not in self._bounds:
            data = self.xData if ax == 0 else self.yData
            finite = None if data is None else data[np.isfinite(data)]
            self._bounds[ax] = ((None, None) if finite is None or finite.size == 0 else
                                (float(finite.min()), float(finite.max())))
        return self._bounds[ax]


def _curve(plot: pg.PlotWidget, color: object, name: str | None = None,
           style: Qt.PenStyle = Qt.PenStyle.SolidLine, sorted_x: bool = True
           ) -> pg.PlotDataItem:
    curve = Curve(pen=pg.mkPen(color, width=1, style=style), name=name)
    plot.addItem(curve)
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
        self.legend = QLabel("")
        self.legend.setObjectName("plotLegend")
        self.legend.setWordWrap(True)
        self.legend_entries: list[tuple[str, Qt.PenStyle, str]] = []
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
        """Remove every curve (and the data it held) and the legend."""
        for plot in self.plots:
            for item in plot.listDataItems():
                plot.removeItem(item)
                item.setData([], [])
                item.deleteLater()
        self.legend_entries.clear()
        self.legend.setText("")
        self._version = -1

    def _legend_add(self, color: str, style: Qt.PenStyle, label: str) -> None:
        self.legend_entries.append((color, style, label))
        self.legend.setText(legend_html(self.legend_entries))

    def points(self) -> int:
        """Samples held by the curves (before display downsampling)."""
        return sum(0 if c.xData is None else c.xData.size
                   for p in self.plots for c in p.listDataItems())


class CompressionPlots(LivePlots):
    """Force against time and against plate position, one colour per step."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        f, t, z = ("force", "N"), ("time from the run's start", "s"), ("plate position", "m")
        self.force_t = self._add(make_plot("Force against time", t, f), 0, 0, ("t", "s"), f)
        self.force_z = self._add(make_plot("Force against plate position", z, f), 0, 1,
                                 ("position", "m"), f)
        self.grid.addWidget(self.legend, 1, 0, 1, 2)
        self.grid.addWidget(self.readout, 2, 0, 1, 2)
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
                label = f"{step.index}. {step.name}"  # the curve's name (not drawn)
                self._t_curves[step.index] = _curve(self.force_t, color, label)
                self._z_curves[step.index] = _curve(self.force_z, color, label, sorted_x=False)
                self._legend_add(color, Qt.PenStyle.SolidLine,
                                 f"step {step.index}: {step.name}")
                self._t_decimators[step.index] = PeakDecimator()
                self._z_decimators[step.index] = PeakDecimator()
            _shift(self._t_curves[step.index], data)
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
    overlap: float = math.nan


class ShearPlots(LivePlots):
    """F_h and F_v against theta for each pass (colour: speed; line: direction), and the
    torque against time (the contact search has no passes)."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        theta, force = ("arc travel theta", "m"), ("force", "N")
        time_axis = ("time from the run's start", "s")
        self.f_h = self._add(make_plot("F_h against theta (per pass)", theta, ("F_h", "N")), 1, 0,
                             ("theta", "m"), ("F_h", "N"))
        self.f_v = self._add(make_plot("F_v against theta (per pass)", theta, ("F_v", "N")), 1, 1,
                             ("theta", "m"), ("F_v", "N"))
        self.torque_t = self._add(make_plot("Torque against time", time_axis,
                                        ("torque", "N*m")), 2, 0, ("t", "s"),
                                  ("torque", "N*m"))
        self.normal_t = self._add(make_plot("Normal force against time", time_axis, force), 2, 1,
                                  ("t", "s"), ("normal force", "N"))
        self.f_h.getPlotItem().setTitle("F_h = s M / L against theta (per pass)")
        top = QHBoxLayout()
        top.addWidget(QLabel("overlap shown:"))
        self.overlap_box = QComboBox()
        self.overlap_box.setObjectName("overlapBox")
        self.overlap_box.setToolTip("the overlap whose passes the theta plots show")
        self.overlap_box.addItem("all overlaps", math.nan)
        self.overlap_box.currentIndexChanged.connect(self._show_overlap)
        top.addWidget(self.overlap_box)
        top.addStretch(1)
        self.grid.addLayout(top, 0, 0, 1, 2)
        self.grid.addWidget(self.legend, 3, 0, 1, 2)
        self.grid.addWidget(self.readout, 4, 0, 1, 2)
        self.grid.setRowStretch(1, 1)
        self.grid.setRowStretch(2, 1)
        self._passes: dict[int, list[_Pass]] = {}
        self._scanned: dict[int, int] = {}
        self._time_curves: dict[int, tuple[pg.PlotDataItem, pg.PlotDataItem]] = {}
        self._speeds: list[float] = []
        self._named: set[tuple[float, float]] = set()
        self._overlaps: list[float] = []

    def clear(self) -> None:
        super().clear()
        self._passes.clear()
        self._scanned.clear()
        self._time_curves.clear()
        self._speeds.clear()
        self._named.clear()
        self._overlaps.clear()
        self.overlap_box.blockSignals(True)
        while self.overlap_box.count() > 1:
            self.overlap_box.removeItem(1)
        self.overlap_box.setCurrentIndex(0)
        self.overlap_box.blockSignals(False)

    def shown_overlap(self) -> float:
        """The overlap (m) whose passes are shown; NaN: all."""
        return float(self.overlap_box.currentData())

    def _show_overlap(self, _index: int = 0) -> None:
        shown = self.shown_overlap()
        for p in (p for passes in self._passes.values() for p in passes):
            visible = math.isnan(shown) or math.isclose(p.overlap, shown, abs_tol=1e-9)
            p.f_h.setVisible(visible)
            p.f_v.setVisible(visible)

    def _add_overlap(self, overlap: float) -> None:
        if math.isnan(overlap) or any(math.isclose(overlap, o, abs_tol=1e-9)
                                      for o in self._overlaps):
            return
        self._overlaps.append(overlap)
        self.overlap_box.addItem(f"overlap {overlap * 1e3:.3g} mm", overlap)

    def _draw(self, data: RunData) -> None:
        for step, cols in data.steps():
            t = cols.get("t_s")
            if t is None or self._scanned.get(step.index) == t.size:
                continue
            if "torque_Nm" in cols:
                if step.index not in self._time_curves:
                    color = STEP_COLOURS[step.index % len(STEP_COLOURS)]
                    label = f"{step.index}. {step.name}"
                    self._time_curves[step.index] = (_curve(self.torque_t, color, label),
                                                     _curve(self.normal_t, color, label))
                    self._legend_add(color, Qt.PenStyle.SolidLine,
                                     f"step {step.index}: {step.name} (time plots)")
                torque, normal = self._time_curves[step.index]
                _shift(torque, data)
                _shift(normal, data)
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
                overlap = float(cols["overlap_m"][i]) if "overlap_m" in cols else math.nan
                passes.append(self._new_pass(float(label), float(cols["speed_m_s"][i]),
                                             float(cols["direction"][i]), i, j, overlap))
                changed.append(passes[-1])
            i = j
        arm = _arm(cols)
        for p in changed:
            theta = cols["theta_m"][p.start: p.end]
            p.f_h.setData(theta, p.direction * cols["torque_Nm"][p.start: p.end] / arm)
            p.f_v.setData(theta, cols["normal_force_N"][p.start: p.end])

    def _new_pass(self, label: float, speed: float, direction: float, start: int,
                  end: int, overlap: float = math.nan) -> _Pass:
        """A pass's curves: colour by speed, line style by direction (solid clockwise,
        dashed counter-clockwise); hidden unless its overlap is the one shown."""
        if speed not in self._speeds:
            self._speeds.append(speed)
        color = colour(self._speeds.index(speed))
        style = Qt.PenStyle.SolidLine if direction >= 0 else Qt.PenStyle.DashLine
        key = (speed, direction)
        if key not in self._named:
            self._named.add(key)
            self._legend_add(color, style,
                             f"{speed_text(speed)} {'cw' if direction >= 0 else 'ccw'}")
        self._add_overlap(overlap)
        p = _Pass(label, speed, direction, start, end,
                  _curve(self.f_h, color, None, style, sorted_x=False),
                  _curve(self.f_v, color, None, style, sorted_x=False), overlap)
        shown = self.shown_overlap()
        if not (math.isnan(shown) or math.isclose(overlap, shown, abs_tol=1e-9)):
            p.f_h.setVisible(False)
            p.f_v.setVisible(False)
        return p

    def pass_count(self) -> int:
        return sum(len(p) for p in self._passes.values())


def _arm(cols: dict[str, FloatArray]) -> float:
    """Arm length L (m) from the stream itself: theta = angle * L."""
    angle, theta = cols["angle_rad"], cols["theta_m"]
    ok = np.flatnonzero(np.abs(angle) > 1e-6)
    if ok.size == 0:
        return math.nan
    return float(theta[ok[0]] / angle[ok[0]])


#: Idle readouts kept for the manual-control plot (5 Hz: the last 20 min).
IDLE_POINTS = 6000
#: What the manual-control plot shows per rig kind: (key, title, SI unit).
IDLE_SERIES: dict[str, tuple[tuple[str, str, str], ...]] = {
    "compression": (("force_N", "force", "N"), ("position_m", "plate position", "m")),
    "shear": (("normal_force_N", "normal force", "N"), ("torque_Nm", "torque", "N*m"),
              ("gap_m", "gap", "m")),
}


class IdlePlots(QWidget):
    """Live force and position (or the rheometer's gap, torque and normal force) from the
    idle readouts, while no run is active: what a manual move does, as it happens. A bounded
    window of the newest readouts; time in s from the first one."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.grid = QGridLayout(self)
        self.grid.setContentsMargins(0, 0, 0, 0)
        self.kind: str | None = None
        self.plots: dict[str, pg.PlotWidget] = {}
        self.curves: dict[str, pg.PlotDataItem] = {}
        self.t: deque[float] = deque(maxlen=IDLE_POINTS)
        self.values: dict[str, deque[float]] = {}
        self._t0: float | None = None
        self.set_kind("compression")

    def set_kind(self, kind: str) -> None:
        if kind == self.kind:
            return
        self.kind = kind
        for plot in self.plots.values():
            plot.deleteLater()
        self.plots.clear()
        self.curves.clear()
        self.values.clear()
        self.t.clear()
        self._t0 = None
        for row, (key, title, unit) in enumerate(IDLE_SERIES.get(kind, ())):
            plot = make_plot(f"{title[0].upper()}{title[1:]} (live, manual control)",
                         ("time", "s"), (title, unit))
            self.grid.addWidget(plot, row, 0)
            self.plots[key] = plot
            self.curves[key] = _curve(plot, colour(row))
            self.values[key] = deque(maxlen=IDLE_POINTS)

    def add(self, values: Mapping[str, float]) -> None:
        """One idle readout (SI values with ``t_s``)."""
        t = values.get("t_s")
        if t is None or not self.curves:
            return
        t0 = self._t0
        if t0 is None or (self.t and t - t0 < self.t[-1]):
            t0 = self.restart(t)  # a new rig's clock (reconnected): time from its first
        self.t.append(t - t0)
        for key, series in self.values.items():
            series.append(values.get(key, math.nan))
        if not self.isVisible():
            return
        times = np.fromiter(self.t, float, len(self.t))
        for key, series in self.values.items():
            self.curves[key].setData(times, np.fromiter(series, float, len(series)))

    def restart(self, t: float) -> float:
        """Start the series afresh at clock time ``t`` (returned): the time axis only ever
        increases."""
        self._t0 = t
        self.t.clear()
        for series in self.values.values():
            series.clear()
        return t

    def points(self) -> int:
        return len(self.t)


def plots_for(kind: str, parent: QWidget | None = None) -> LivePlots:
    return ShearPlots(parent) if kind == "shear" else CompressionPlots(parent)
