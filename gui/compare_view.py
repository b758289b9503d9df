"""Two or more finished runs overlaid (the Results tab; issue 28, item 5): their main curves on
shared axes and their fitted values side by side.

The curves and the table are those of ``gelrig runs ROOT --compare`` (``gelrig.compare``):
for a compression run, force against time from each hold's start and force against the
stage position; for a shear run, the largest |F_h| and F_v of each pass of a ladder. One
colour per run, named by its folder and sample.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QGridLayout,
    QHeaderView,
    QLabel,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from gelrig.catalog import LoadedRun, load_run
from gelrig.compare import HoldCurve, compare_rows, hold_curves, pass_peaks
from gelrig.gui.plots import colour, legend_html, make_plot

#: The panels: key, title, x (name, SI unit), y (name, SI unit).
PANELS = (("force_t", "force in each hold", ("time from the step's start", "s"),
           ("force", "N")),
          ("force_z", "force against position", ("stage position", "m"), ("force", "N")),
          ("f_h", "largest |F_h| per pass", ("pass", ""), ("|F_h|", "N")),
          ("f_v", "largest F_v per pass", ("pass", ""), ("F_v", "N")))
#: Line styles of a run's second, third... hold.
_STYLES = (Qt.PenStyle.SolidLine, Qt.PenStyle.DashLine, Qt.PenStyle.DotLine,
           Qt.PenStyle.DashDotLine)


def label(run: LoadedRun) -> str:
    """A run's name in a legend: ``<folder> (<sample>)``."""
    return f"{run.path.name} ({run.sample or 'no sample'})"


@dataclass(frozen=True)
class RunCurves:
    """What is drawn of one run: its legend label, its holds, its ladders' peaks per pass."""

    name: str
    label: str
    holds: list[HoldCurve]
    ladders: list[tuple[Any, Any, Any]]


def curves_of(path: str | Path) -> RunCurves:
    """Read a run's curves (off the GUI thread: the step files are read here)."""
    run = load_run(path)
    return RunCurves(run.path.name, label(run), hold_curves(run), pass_peaks(run))


class CompareView(QWidget):
    """The overlay plots (only the panels some run has data for) above the side-by-side
    table of results with 95 % intervals."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.note = QLabel("select two runs or more and press Compare")
        self.note.setWordWrap(True)
        layout.addWidget(self.note)
        # one legend for every panel, above them: inside a plot it lay over some run's curve
        # (runs of other depths leave no corner free; seen at 2x)
        self.legend = QLabel("")
        self.legend.setWordWrap(True)
        self.legend.setObjectName("compareLegend")
        self.legend_entries: list[tuple[str, Qt.PenStyle, str]] = []
        layout.addWidget(self.legend)
        split = QSplitter(Qt.Orientation.Vertical)
        holder = QWidget()
        self.grid = QGridLayout(holder)
        self.grid.setContentsMargins(0, 0, 0, 0)
        self.plots: dict[str, pg.PlotWidget] = {}
        for key, title, x, y in PANELS:
            plot = make_plot(title, x, y)
            plot.setObjectName(f"compare_{key}")
            self.plots[key] = plot
        self.table = QTableWidget(0, 0)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.table.horizontalHeader().setSectionResizeMode(
            QHeaderView.ResizeMode.ResizeToContents)
        split.addWidget(holder)
        split.addWidget(self.table)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        split.setSizes([330, 170])
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(self.fontMetrics().height() + 6)
        layout.addWidget(split, 1)

    def curves(self, key: str) -> list[pg.PlotDataItem]:
        """The curves drawn in panel ``key`` (``force_t``, ``force_z``, ``f_h``, ``f_v``)."""
        return list(self.plots[key].getPlotItem().listDataItems())

    def show_runs(self, runs: Sequence[RunCurves], entries: Sequence[Mapping[str, Any]]
                  ) -> list[str]:
        """Overlay ``runs`` (their catalog ``entries`` in the same order give the table);
        returns notes on runs with nothing to draw."""
        for plot in self.plots.values():
            plot.getPlotItem().clear()
        notes = []
        self.legend_entries = []
        for k, run in enumerate(runs):
            pen_colour = colour(k)
            self.legend_entries.append((pen_colour, Qt.PenStyle.SolidLine, run.label))
            for n, hold in enumerate(run.holds):
                pen = pg.mkPen(pen_colour, width=1.5, style=_STYLES[n % len(_STYLES)])
                name = run.label if n == 0 else None
                self._draw("force_t", hold.t, hold.force, pen, name)
                if hold.position is not None:
                    self._draw("force_z", hold.position, hold.force, pen, name)
            for n, (index, f_h, f_v) in enumerate(run.ladders):
                pen = pg.mkPen(pen_colour, width=1.5, style=_STYLES[n % len(_STYLES)])
                name = run.label if n == 0 else None
                for key, values in (("f_h", f_h), ("f_v", f_v)):
                    self.plots[key].plot(index, values, pen=pen, symbol="o", symbolSize=5,
                                         symbolBrush=pen_colour, name=name)
            if not run.holds and not any(index.size for index, _h, _v in run.ladders):
                notes.append(f"{run.name}: no hold or ladder recorded")
        self._arrange()
        self.legend.setText(legend_html(self.legend_entries))
        self._fill_table(compare_rows(entries))
        self.note.setText("; ".join(notes) if notes else
                          f"{len(runs)} runs overlaid; values with 95 % intervals below")
        return notes

    def _draw(self, key: str, x: Any, y: Any, pen: Any, name: str | None) -> None:
        curve = self.plots[key].plot(x, y, pen=pen, name=name)
        curve.setDownsampling(auto=True, method="peak")
        curve.setClipToView(True)

    def _arrange(self) -> None:
        """Lay out the panels that have curves, two a row (the hold panels if none has)."""
        for plot in self.plots.values():
            self.grid.removeWidget(plot)
            plot.setVisible(False)
        shown = [key for key, *_ in PANELS if self.curves(key)] or ["force_t", "force_z"]
        for i, key in enumerate(shown):
            self.grid.addWidget(self.plots[key], i // 2, i % 2)
            self.plots[key].setVisible(True)
            self.plots[key].getPlotItem().enableAutoRange()

    def _fill_table(self, rows: list[list[str]]) -> None:
        head, body = rows[0], rows[1:]
        self.table.clear()
        self.table.setColumnCount(len(head))
        self.table.setRowCount(len(body))
        self.table.setHorizontalHeaderLabels(head)
        for r, row in enumerate(body):
            for c, text in enumerate(row):
                self.table.setItem(r, c, QTableWidgetItem(text))
