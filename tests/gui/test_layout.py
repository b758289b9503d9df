"""The window at the rig (issue 15): value fields that the wheel cannot change unless focused,
STOP in reach (Escape, 2x scaling), title and menus, plots a scientist reads at a glance,
bounded memory across runs, the live manual plot, export."""

import csv
import gc
import json
import math
import os
import subprocess
import sys
import weakref
from pathlib import Path

import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication, QScrollArea

from gelrig.gui import mainwindow
from gelrig.gui.fmt import quantity
from gelrig.gui.plots import ShearPlots
from gelrig.protocols.events import RunState
from tests.gui import test_app
from tests.gui.test_app import confirm_moves, home, short_compression, stage_sim, wait_finished

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig

ROOT = Path(__file__).resolve().parents[2]


def wheel(widget, steps=1):
    """A wheel turn of ``steps`` notches over the middle of ``widget``, as the mouse gives it."""
    centre = QPointF(widget.rect().center())
    event = QWheelEvent(centre, QPointF(widget.mapToGlobal(centre.toPoint())), QPoint(),
                        QPoint(0, 120 * steps), Qt.MouseButton.NoButton,
                        Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)


def test_the_wheel_changes_a_value_field_only_when_it_has_focus(qtbot, open_window):
    window = open_window(math.inf)
    window.left_tabs.setCurrentIndex(1)  # manual control
    speed = window.manual.entries["speed"]
    qtbot.waitUntil(speed.isVisible, timeout=5_000)
    assert speed.focusPolicy() == Qt.FocusPolicy.StrongFocus
    window.pace_box.clearFocus()
    before = {key: box.value() for key, box in window.manual.entries.items()}
    for box in window.manual.entries.values():
        box.clearFocus()
        wheel(box, 3)
    assert {key: box.value() for key, box in window.manual.entries.items()} == before
    pace = window.pace_box.currentIndex()
    wheel(window.pace_box, -1)
    assert window.pace_box.currentIndex() == pace
    # Focused (clicked or tabbed into), the wheel does change it: the guard is not a lock.
    speed.setFocus()
    qtbot.waitUntil(speed.hasFocus, timeout=2_000)
    wheel(speed, 1)
    assert speed.value() == before["speed"] + speed.singleStep()


def test_stop_and_the_manual_controls_are_outside_the_scroll_areas(qtbot, open_window):
    window = open_window(math.inf)
    scrolls = window.findChildren(QScrollArea)
    assert scrolls
    for scroll in scrolls:
        assert not scroll.isAncestorOf(window.stop_button)
    assert window.stop_button.isVisible() and window.stop_button.isEnabled()
    # the stage position is in the header, beside whichever tab is shown
    qtbot.waitUntil(lambda: "position" in window.header.readout.text(), timeout=5_000)
    window.left_tabs.setCurrentIndex(1)
    qtbot.waitUntil(lambda: window.manual.buttons["move_to"].isVisible(), timeout=5_000)
    assert window.header.readout.isVisible()


def test_escape_stops_a_manual_move_from_any_widget(qtbot, open_window, monkeypatch):
    window = open_window(10.0)
    confirm_moves(monkeypatch)
    sim, clock = stage_sim(window), window.desk.clock
    window.left_tabs.setCurrentIndex(1)
    manual = window.manual
    home(qtbot, window)
    manual.entries["speed"].setValue(0.5)
    manual.entries["target"].setValue(4.0)
    manual.buttons["move_to"].click()
    qtbot.waitUntil(lambda: sim.velocity_at(clock.now()) > 0, timeout=5_000)
    target = manual.entries["target"]
    target.setFocus()
    qtbot.keyClick(target, Qt.Key.Key_Escape)
    qtbot.waitUntil(lambda: sim.velocity_at(clock.now()) == 0.0, timeout=5_000)
    assert sim.position_at(clock.now()) < 3.0e-3  # stopped well short of 4 mm
    assert "STOP" in window.log.toPlainText()


def probed(script: str, tmp_path: Path, screen: tuple[int, int], scale: int) -> dict:
    """What the probe ``script`` (tests/gui) wrote, run in a subprocess on an offscreen
    screen of ``screen`` pixels at ``QT_SCALE_FACTOR=scale``."""
    config = tmp_path / "screen.json"
    config.write_text(json.dumps({"screens": [{"name": "s", "x": 0, "y": 0,
                                               "width": screen[0], "height": screen[1],
                                               "logicalDpi": 96, "dpr": 1}]}))
    env = {**os.environ, "QT_SCALE_FACTOR": str(scale), "PYTHONPATH": str(ROOT),
           "QT_QPA_PLATFORM": f"offscreen:configfile={config}"}
    found = tmp_path / "probe.json"
    out = subprocess.run([sys.executable, str(ROOT / "tests" / "gui" / script),
                          str(tmp_path / "runs"), str(found)],
                         env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and found.exists(), (out.stdout[-1000:], out.stderr[-2000:])
    return json.loads(found.read_text())


@pytest.mark.parametrize(("screen", "scale"), [((1280, 720), 1), ((1280, 720), 2),
                                               ((2560, 1440), 2)])
def test_every_dialog_lies_within_the_screen_at_1280x720_and_at_2x(tmp_path, screen, scale):
    """The fault message (a long one keeps its first paragraph and the rest in its scrolling
    details), the close-loaded and pause-in-hold questions, the file choosers (resizable,
    shrunk to the screen) and About, each on a 1280x720 screen, at 2x on it (640x360
    logical) and at 2x on 2560x1440."""
    probe = probed("dialog_probe.py", tmp_path, screen, scale)
    left, top, width, height = probe.pop("screen")
    assert [width, height] == [screen[0] // scale, screen[1] // scale]
    assert set(probe) == {"fault", "long fault", "about", "close loaded", "pause in hold",
                          "open protocol", "open rig", "open run", "save protocol as"}
    for name, shown in probe.items():
        x, y, w, h = shown["frame"]
        assert left <= x and top <= y and x + w <= left + width and y + h <= top + height, \
            (name, shown, screen, scale)
        assert shown["message"] or not shown["fixed"], name  # a chooser can be resized
    assert probe["long fault"]["details"] and not probe["fault"]["details"]


@pytest.mark.parametrize(("screen", "scale"), [((1440, 900), 2), ((1280, 720), 1)])
def test_stop_and_the_status_bar_lie_in_the_window_at_2x_and_at_1280x720(tmp_path, screen,
                                                                           scale):
    """In a subprocess: the scale factor and the screen are fixed when Qt starts."""
    probe = probed("layout_probe.py", tmp_path, screen, scale)
    logical = [screen[0] // scale, screen[1] // scale]  # 720x450 at 2x
    assert probe["screen"] == logical
    width, height = probe["window"]
    assert width <= logical[0] and height <= logical[1]
    for name in ("stop", "status"):
        x, y, w, h = probe[name]
        assert probe[f"{name}_visible"], name
        assert x >= 0 and x + w <= width and y >= 0 and y + h <= height, (name, probe)
    assert "run_window" in probe, ("the short run did not finish within 90 s", probe)
    x, y, w, h = probe["run_window"]  # Open run: within the screen, and may shrink more
    assert x >= 0 and y >= 0 and x + w <= logical[0] and y + h <= logical[1], probe
    assert probe["run_window_min"][0] <= w and probe["run_window_min"][1] <= h, probe


def test_title_menus_and_open_run_start_where_the_runs_are(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    assert "Plate-compression rig" in window.windowTitle()
    assert "simulated" in window.windowTitle()
    menus = {a.text().replace("&", ""): a.menu() for a in window.menuBar().actions()}
    assert set(menus) == {"File", "Rig", "View", "Help"}
    file_items = [a.text().replace("&", "") for a in menus["File"].actions() if a.text()]
    for item in ("Open rig…", "Open protocol…", "Open run…", "Export plot as PNG…",
                 "Export data as CSV…", "Open report"):
        assert item in file_items
    assert [a.text().replace("&", "") for a in menus["Help"].actions()] == ["About gelrig"]
    (tmp_path / "runs").mkdir(exist_ok=True)
    assert window.runs_dir() == tmp_path / "runs"


def test_a_run_titles_the_window_numbers_steps_as_stored_and_shows_results(qtbot, open_window,
                                                                          tmp_path,
                                                                          monkeypatch):
    window = open_window(math.inf)
    assert not window.report_button.isVisible()
    window.protocol.set_table(short_compression(hold="5 s"), "<test>")
    window.protocol.run_button.click()
    assert wait_finished(qtbot, window) == RunState.COMPLETED
    run = window.desk.run_path
    assert f"run {run.name} (completed)" in window.windowTitle()
    assert window.report_button.isVisible() and window.report_action.isEnabled()
    meta = json.loads((run / "run.json").read_text())
    stored = [f"step {s['index']}: {s['name']}" for s in meta["steps"]]
    plots = window.plots
    assert [label for _c, _s, label in plots.legend_entries] == stored
    for s in meta["steps"]:
        assert f"step {s['index']} started: {s['name']}" in window.log.toPlainText()
    # time from the run's start: the first sample drawn at 0 s
    t0 = window.desk.data.t0
    first = min(c.pos().x() + c.xData[0] for c in plots.force_t.listDataItems())
    starts = [(s.index, c["t_s"][0], c["t_s"][-1]) for s, c in window.desk.data.steps()]
    items = [(c.name(), c.pos().x(), c.xData[0]) for c in plots.force_t.listDataItems()]
    assert first == 0.0 and t0 > 1.0, (t0, starts, items)  # the clock ran before the run
    assert plots.force_z.getPlotItem().getAxis("bottom").labelText == "plate position (mm)"
    # the contact search's result, in words, when the step completed
    touch = meta["steps"][0]["results"]["first_touch_m"]
    log = window.log.toPlainText()
    assert f"step 0 result: first touch {quantity(touch, 'm', 6)} (spread" in log, log[-3000:]

    opened = []
    monkeypatch.setattr(mainwindow.QDesktopServices, "openUrl", opened.append)
    window.report_button.click()  # analyses the run, then opens its HTML report
    qtbot.waitUntil(lambda: bool(opened), timeout=60_000)
    assert opened[0].toLocalFile() == str((run / "analysis" / "report.html").resolve())

    png = window.export_png(tmp_path / "plot.png")
    assert png is not None and png.stat().st_size > 1000
    rows = window.export_csv(tmp_path / "data.csv")
    with rows.open() as f:
        table = list(csv.reader(f))
    assert table[0][:3] == ["step", "t_s", "force_N"]
    assert len(table) - 1 == window.desk.data.samples()
    assert {row[0] for row in table[1:]} == {"0", "1"}


def test_a_finished_run_s_buffers_are_released_when_the_next_run_starts(qtbot, open_window):
    window = open_window(math.inf)
    window.protocol.set_table(short_compression(hold="2 s"), "<test>")
    window.protocol.run_button.click()
    assert wait_finished(qtbot, window) == RunState.COMPLETED
    first = weakref.ref(window.desk.data)
    curves = [weakref.ref(c) for c in window.plots.force_t.listDataItems()]
    window.protocol.run_button.click()
    assert wait_finished(qtbot, window) == RunState.COMPLETED
    qtbot.wait(50)  # deleteLater
    gc.collect()
    assert first() is None
    assert all(c() is None for c in curves)

    viewer = window.open_run(window.desk.run_path)
    held = weakref.ref(viewer.data)
    viewer.close()
    qtbot.waitUntil(lambda: not window.run_windows, timeout=5_000)
    del viewer
    gc.collect()
    assert held() is None


def test_the_manual_tab_plots_force_and_position_live(qtbot, open_window, monkeypatch):
    window = open_window(10.0)
    confirm_moves(monkeypatch)
    window.left_tabs.setCurrentIndex(1)
    home(qtbot, window)  # a move before homing asks to home first
    window.manual.entries["target"].setValue(1.0)
    window.manual.buttons["move_to"].click()
    assert window.plot_tabs.currentWidget() is window.idle_plots
    position = window.idle_plots.curves["position_m"]
    qtbot.waitUntil(lambda: position.yData is not None and position.yData.max() > 0.5e-3,
                    timeout=15_000)
    assert window.idle_plots.curves["force_N"].yData.size == position.yData.size
    window.stop()


def test_shear_theta_plots_show_speeds_in_um_s_and_one_overlap_at_a_time(qtbot, open_window):
    window = open_window(math.inf, rig="shear")
    window.protocol.set_table({"protocol": {"name": "ladder", "rig": "shear"}, "step": [
        {"kind": "speed_ladder", "overlaps": 2, "first_overlap": "0.4 mm",
         "overlap_step": "0.1 mm", "speeds": ["1e-4 m/s"], "travel": "3 mm", "wait": "1 s",
         "interval": "0.05 s", "read_period": "0.5 s", "touch_gap": "3 mm",
         "centre_angle": 0.8}]}, "<test>")
    assert window.protocol.run_button.isEnabled(), window.protocol.why_not
    window.protocol.run_button.click()
    assert wait_finished(qtbot, window) == RunState.COMPLETED
    plots = window.plots
    assert isinstance(plots, ShearPlots)
    assert sorted(label for _c, _s, label in plots.legend_entries
                  if "step" not in label) == ["100 µm/s ccw", "100 µm/s cw"]
    box = plots.overlap_box
    assert [box.itemText(i) for i in range(box.count())] == [
        "all overlaps", "overlap 0.4 mm", "overlap 0.5 mm"]
    assert sum(c.isVisible() for c in plots.f_h.listDataItems()) == 4
    box.setCurrentIndex(2)
    shown = [c for c in plots.f_h.listDataItems() if c.isVisible()]
    assert len(shown) == 2  # the two passes (cw, ccw) at 0.5 mm
    axis = plots.torque_t.getPlotItem().getAxis("left")
    assert axis.labelText == "torque (mN*m)" and axis.scale == 1e3
    assert plots.f_h.getPlotItem().getAxis("bottom").labelText == "arc travel theta (mm)"
