"""A crosshair on a plot that reads out where it points, in physical units."""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import QObject, QPointF, Qt
from PySide6.QtWidgets import QLabel

from gelrig.gui.fmt import quantity


class Crosshair(QObject):
    """Follows the mouse over ``plot`` and writes 'x = 6.2 mm   y = 4.1 mN' to ``readout``."""

    def __init__(self, plot: pg.PlotWidget, readout: QLabel, x: tuple[str, str],
                 y: tuple[str, str]):
        super().__init__(plot)
        self.plot = plot
        self.readout = readout
        self.x_name, self.x_unit = x
        self.y_name, self.y_unit = y
        pen = pg.mkPen((120, 120, 120), width=1, style=Qt.PenStyle.DashLine)
        self.v_line = pg.InfiniteLine(angle=90, movable=False, pen=pen)
        self.h_line = pg.InfiniteLine(angle=0, movable=False, pen=pen)
        for line in (self.v_line, self.h_line):
            line.setVisible(False)
            plot.addItem(line, ignoreBounds=True)
        plot.scene().sigMouseMoved.connect(self.move_to)

    def text_at(self, x: float, y: float) -> str:
        return (f"{self.x_name} = {quantity(x, self.x_unit)}    "
                f"{self.y_name} = {quantity(y, self.y_unit)}")

    def move_to(self, scene_pos: QPointF) -> None:
        view = self.plot.getPlotItem().getViewBox()
        inside = view.sceneBoundingRect().contains(scene_pos)
        self.v_line.setVisible(inside)
        self.h_line.setVisible(inside)
        if not inside:
            return
        point = view.mapSceneToView(scene_pos)
        self.v_line.setPos(point.x())
        self.h_line.setPos(point.y())
        self.readout.setText(self.text_at(point.x(), point.y()))
