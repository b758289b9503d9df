"""What the window shows at its edges (issue 25, item 8): a tooltip with unit and allowed range
on every input field, time axes in s / min / h by the span shown, light or dark as the
system says (or as View > Appearance says), and where the report is when no browser opens."""

import math

import pyqtgraph as pg
import pytest
from PySide6.QtGui import QDesktopServices, QPalette
from PySide6.QtWidgets import QAbstractSpinBox, QApplication, QComboBox, QLineEdit

from gelrig.gui import theme
from gelrig.gui.plots import TimeAxis
from tests.gui import test_app

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig

SHEAR = {"protocol": {"name": "ladder", "rig": "shear"}, "step": [
    {"kind": "speed_ladder", "overlaps": 1, "first_overlap": "0.4 mm",
     "speeds": ["1e-4 m/s", "2e-4 m/s"], "travel": "4 mm", "wait": "1 s"}]}


def input_fields(window):
    """Every field a person types or picks a value in (not a spin box's own line edit)."""
    fields = window.findChildren(QLineEdit) + window.findChildren(QAbstractSpinBox) + \
        window.findChildren(QComboBox)
    return [f for f in fields if not isinstance(f.parent(), QAbstractSpinBox | QComboBox)]


@pytest.mark.parametrize(("rig", "table"), [("compression", test_app.short_compression()),
                                            ("shear", SHEAR)])
def test_every_input_field_has_a_tooltip(qtbot, open_window, rig, table):
    window = open_window(math.inf, rig)
    window.protocol.set_table(table, "<table>")
    fields = input_fields(window)
    assert len(fields) > 5
    bare = [f.objectName() or type(f).__name__ for f in fields if not f.toolTip().strip()]
    assert bare == []
    speed = window.manual.entries["speed"]
    assert "mm/s" in speed.toolTip() and "allowed" in speed.toolTip()
    if rig == "compression":
        assert "allowed 0.001 to 2.3 mm/s" in speed.toolTip()
        assert "allowed" in window.protocol.form.entry(1, "strain_rate").edit.toolTip()
    else:
        assert "rpm" in speed.toolTip()  # the arm's speed and its rpm


@pytest.mark.parametrize(("span", "unit", "tick"), [(100.0, "s", "60"), (3600.0, "min", "30"),
                                                    (36_000.0, "h", "5")])
def test_time_axes_read_in_s_min_or_h_by_the_span_shown(qtbot, span, unit, tick):
    plot = pg.PlotWidget(axisItems={"bottom": TimeAxis("time from the run's start")})
    qtbot.addWidget(plot)
    plot.resize(600, 300)
    plot.show()
    plot.setXRange(0.0, span, padding=0)
    axis = plot.getPlotItem().getAxis("bottom")
    assert axis.unit == unit and axis.labelText == f"time from the run's start ({unit})"
    assert "ks" not in axis.labelString()
    ticks = [s for level in axis.tickValues(0.0, span, 600) for s in
             axis.tickStrings(level[1], axis.scale, level[0])]
    assert tick in ticks  # 60 s, 30 min, 5 h: round values of the unit


def test_the_windows_time_plots_use_the_time_axis(qtbot, open_window):
    window = open_window(math.inf)
    axes = [p.getPlotItem().getAxis("bottom") for p in window.findChildren(pg.PlotWidget)]
    times = [a for a in axes if "time" in a.labelText]
    assert len(times) >= 4 and all(isinstance(a, TimeAxis) for a in times)


def lightness(colour) -> int:
    return colour.lightness()


def test_appearance_follows_the_system_unless_the_view_menu_says(qtbot, open_window):
    assert theme.is_dark("system", True) and not theme.is_dark("system", False)
    assert theme.is_dark("dark", False) and not theme.is_dark("light", True)
    with pytest.raises(ValueError):
        theme.is_dark("blue", False)
    window = open_window(math.inf)
    assert window.appearance == "system"  # nothing remembered: as the system says
    assert window.appearance_actions["system"].isChecked()
    window.appearance_actions["dark"].trigger()
    plots = window.findChildren(pg.PlotWidget)
    assert all(lightness(p.backgroundBrush().color()) < 64 for p in plots)
    qtbot.waitUntil(lambda: lightness(window.palette().color(QPalette.ColorRole.Window)) < 64,
                    timeout=5_000)
    assert lightness(window.palette().color(QPalette.ColorRole.WindowText)) > 192
    window.appearance_actions["light"].trigger()
    assert all(lightness(p.backgroundBrush().color()) > 192 for p in plots)
    qtbot.waitUntil(lambda: lightness(window.palette().color(QPalette.ColorRole.Window)) > 128,
                    timeout=5_000)
    window.set_appearance("dark")
    window._save_settings()  # remembered for the next window
    again = open_window(math.inf)
    assert again.appearance == "dark" and again.appearance_actions["dark"].isChecked()
    again.set_appearance("system")


def test_open_report_says_where_the_file_is_when_no_browser_opens(qtbot, open_window,
                                                                  tmp_path, monkeypatch):
    window = open_window(math.inf)
    report = tmp_path / "run" / "analysis" / "report.html"
    report.parent.mkdir(parents=True)
    report.write_text("<html></html>")
    monkeypatch.setattr(QDesktopServices, "openUrl", staticmethod(lambda url: False))
    assert window._show_report(report) is False
    box = window.last_message
    assert box is not None and "No browser opened" in box.text()
    assert str(report.resolve()) in box.text()
    assert f"the report is at {report.resolve()}" in window.log.toPlainText()


def test_the_status_line_is_elided_never_cut_and_never_widens_the_window(qtbot, open_window):
    window = open_window(math.inf)
    width = window.width()
    line = ("NOT MONITORING: USB-6001 silent for 3 s (The link to the force DAQ (USB-6001) was "
            "lost: check its power and cable, then Disconnect and Connect the rig); last stop: "
            "motion stopped (verified); plate retracted to 0.000 mm") * 3
    label = window.safety_label
    label.set_line(line)
    QApplication.processEvents()
    assert window.width() == width and label.width() < len(line) * 3
    assert label.text().endswith("…") and line.startswith(label.text()[:-1])
    assert label.full == line and line in label.toolTip()
    label.set_line("interlocks armed")
    assert label.text() == "interlocks armed"
