"""The application on the built-in simulated rigs, driven through its buttons (pytest-qt,
offscreen): a short compression run whose plots receive the data, pause / resume / abort,
validation as you type, an injected fault, manual control, a mid-run screenshot, closing
mid-run, and the shear rig's per-pass plots."""

import dataclasses
import json
import math
import time

import h5py
import numpy as np
import pytest
from PySide6.QtGui import QColor, QImage

from gelrig.commands.gui import make_services
from gelrig.gui import dialogs
from gelrig.gui.binding import binding_problem
from gelrig.gui.mainwindow import MainWindow
from gelrig.gui.plots import CompressionPlots, ShearPlots, colour
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import default_rig
from gelrig.simulators.kdc101.protocol_kdc101sim import lookup

BINDING = binding_problem()
PACES = {1.0: 0, 10.0: 1, 100.0: 2, math.inf: 3}


def short_compression(hold="20 s", confirm=1):
    """Contact search from 5 mm (the sphere is at 6.2 mm) and a 1 % ramp with a short hold."""
    return {"protocol": {"name": "short compression", "rig": "compression"}, "step": [
        {"kind": "compression_contact_search", "start": "5 mm", "confirm": confirm,
         "tare_time": "0.2 s"},
        {"kind": "ramp_hold", "diameter": "18.63 mm", "strain": 0.01, "strain_rate": "0.01 /s",
         "hold": hold,
         "rate": "1000 Hz", "retract": "0.5 mm", "terms": 1}]}


@pytest.fixture
def open_window(qtbot, tmp_path):
    """open_window(pace, rig) -> a MainWindow connected to a built-in simulated rig; the rigs
    the factory built are kept in ``window.built`` (to reach their simulators)."""
    if BINDING:
        pytest.fail(BINDING)
    windows = []

    def make(pace=math.inf, rig="compression"):
        built = []
        base = make_services(default_rig(rig), pace, tmp_path / "runs")

        def build(spec, clock):
            built.append(base.build_rig(spec, clock))
            return built[-1]

        window = MainWindow(dataclasses.replace(base, build_rig=build))
        window.built = built
        windows.append(window)
        window.show()
        window.start()
        qtbot.waitUntil(lambda: window.desk.rig is not None, timeout=20_000)
        return window

    yield make
    for window in windows:
        if window.desk.running:
            window.desk.abort("test teardown")
            qtbot.waitUntil(lambda w=window: not w.desk.running, timeout=20_000)
        window._leave_loaded = True  # teardown: close without asking about the sample
        window.close()


def home(qtbot, window):
    """Home the stage from the manual panel and wait until it is homed and at rest."""
    window.manual.buttons["home"].click()
    qtbot.waitUntil(lambda: window.instruments.values["homed"].text() == "yes", timeout=15_000)
    qtbot.waitUntil(lambda: window.instruments.values["moving"].text() == "at rest"
                    and not window.desk.moving_by_hand, timeout=15_000)


def confirm_moves(monkeypatch):
    """Answer yes to every question: moves toward the sample before a contact search."""
    monkeypatch.setattr(dialogs, "ask", lambda parent, title, text, on_answer, *a, **k:
                        on_answer("yes"))


def stage_sim(window):
    address = window.desk.rig.identities["stage"]["address"]
    return lookup(address.split("://", 1)[1])


def wait_finished(qtbot, window, timeout=30_000):
    qtbot.waitUntil(lambda: not window.desk.running and window.protocol.state.finished,
                    timeout=timeout)
    return window.protocol.state


def samples_in(window, step):
    steps = dict((s.index, cols) for s, cols in window.desk.data.steps())
    return steps[step]["t_s"].size if step in steps else 0


def test_short_compression_run_fills_the_plots_and_opens_as_a_finished_run(qtbot,
                                                                           open_window):
    window = open_window(math.inf)
    assert window.instruments.values["position_m"] is not None
    window.protocol.set_table(short_compression(), "<test>")
    assert window.protocol.run_button.isEnabled(), window.protocol.why_not
    assert "limit checks all passed" in window.protocol.plan_text.toPlainText()
    window.protocol.run_button.click()
    assert wait_finished(qtbot, window) == RunState.COMPLETED

    plots = window.plots
    assert isinstance(plots, CompressionPlots)
    n = window.desk.data.samples()
    assert n > 20_000  # the 20 s hold at 1 kHz and the search
    assert plots.points() == n
    steps = {s.index: cols for s, cols in window.desk.data.steps()}
    hold = steps[1]
    by_name = {c.name(): c for c in plots.force_t.listDataItems()}
    curve = by_name["1. ramp and hold"]
    # Full view: a peak decimation that ends at the newest sample and keeps the extremes.
    assert 1000 < curve.xData.size <= hold["t_s"].size
    assert curve.xData[-1] == hold["t_s"][-1]
    assert curve.yData.max() == hold["force_N"].max()
    assert curve.yData.min() == hold["force_N"].min()
    z_curve = {c.name(): c for c in plots.force_z.listDataItems()}["1. ramp and hold"]
    assert z_curve.xData.max() == hold["position_m"].max()
    # Zoomed in: the samples themselves.
    plots.force_t.getPlotItem().getViewBox().setXRange(hold["t_s"][100], hold["t_s"][200])
    qtbot.waitUntil(lambda: curve.xData.size == hold["t_s"].size, timeout=2_000)
    np.testing.assert_array_equal(curve.yData, hold["force_N"])
    plots.force_t.getPlotItem().getViewBox().enableAutoRange()
    qtbot.waitUntil(lambda: curve.xData.size < hold["t_s"].size, timeout=2_000)
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "completed" and meta["clock"] == "paced:inf"
    assert sum(s["samples"] for s in meta["steps"]) == n  # the plots saw what was recorded
    (_s, cols), = [(s, c) for s, c in window.desk.data.steps() if s.index == 1]
    with h5py.File(window.desk.run_path / meta["steps"][1]["file"]) as f:
        np.testing.assert_array_equal(f["force_N"][:], cols["force_N"])
    assert window.protocol.progress.value() == 1000
    assert "completed" in window.log.toPlainText()

    viewer = window.open_run(window.desk.run_path)
    assert viewer is not None
    assert viewer.plots.points() == n
    shown = {c.name(): c for c in viewer.plots.force_t.listDataItems()}
    assert shown["1. ramp and hold"].xData[-1] == hold["t_s"][-1]
    assert "first touch" in viewer.stored  # what run.json holds, shown at once
    qtbot.waitUntil(lambda: viewer.analysed, timeout=30_000)  # then gelrig analyze's summary
    summary = viewer.summary.toPlainText()
    assert "Hold, step 1" in summary and "report:" in summary, summary
    viewer.close()


def test_pause_resume_and_abort_from_the_buttons(qtbot, open_window):
    window = open_window(10.0)
    panel = window.protocol
    panel.set_table(short_compression(hold="300 s"), "<test>")
    panel.run_button.click()
    panel.pause_button.click()  # takes effect at the first checkpoint
    qtbot.waitUntil(lambda: panel.state == RunState.PAUSED, timeout=20_000)
    assert panel.resume_button.isEnabled() and not panel.pause_button.isEnabled()
    assert not window.manual.buttons["home"].isEnabled()  # no manual moves during a run
    assert window.stop_button.isEnabled()
    sim, clock = stage_sim(window), window.desk.clock
    n = window.desk.data.samples()
    qtbot.wait(300)
    assert window.desk.data.samples() == n  # nothing acquired or moved while paused
    assert sim.velocity_at(clock.now()) == 0.0

    panel.resume_button.click()
    qtbot.waitUntil(lambda: panel.state == RunState.RUNNING, timeout=5_000)
    window.pace_box.setCurrentIndex(PACES[100.0])
    qtbot.waitUntil(lambda: samples_in(window, 1) > 1000, timeout=30_000)
    panel.abort_button.click()
    assert wait_finished(qtbot, window) == RunState.ABORTED
    assert sim.velocity_at(clock.now()) == 0.0
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "aborted"
    assert meta["steps"][1]["status"] == "aborted" and meta["steps"][1]["samples"] > 1000
    assert window.manual.buttons["home"].isEnabled()  # manual control is back


def test_an_invalid_parameter_shows_its_message_and_disables_run(qtbot, open_window):
    window = open_window(math.inf)
    panel = window.protocol
    panel.set_table(short_compression(), "<test>")
    assert panel.run_button.isEnabled()
    entry = panel.form.entry(0, "speed")
    entry.edit.clear()
    qtbot.keyClicks(entry.edit, "5 mm/s")  # over the 2.3 mm/s the step allows
    assert not panel.run_button.isEnabled()
    qtbot.waitUntil(entry.error.isVisible, timeout=2_000)  # beside the field
    assert entry.error.text() == "allowed (0, 2.3] mm/s"
    entry.edit.clear()
    qtbot.keyClicks(entry.edit, "0.3 mm")  # wrong dimension
    assert not panel.run_button.isEnabled() and "m/s" in entry.error.text()
    entry.edit.clear()
    qtbot.keyClicks(entry.edit, "0.3 mm/s")
    assert panel.run_button.isEnabled() and entry.error.isHidden()
    assert panel.spec.steps[0].params.speed == pytest.approx(0.3e-3)
    strain = panel.form.entry(1, "strain")
    strain.edit.setText("0.2")  # valid alone, but 3.7 mm deep is past the 2.5 mm overlap limit
    assert not panel.run_button.isEnabled()
    assert "limit check failed" in panel.why_not and "FAIL" in panel.plan_text.toPlainText()


def test_a_fault_in_the_stage_shows_the_message_and_stops_motion(qtbot, open_window):
    window = open_window(10.0)
    window.protocol.set_table(short_compression(hold="300 s"), "<test>")
    window.protocol.run_button.click()
    sim, clock = stage_sim(window), window.desk.clock
    qtbot.waitUntil(lambda: samples_in(window, 0) > 20 and sim.velocity_at(clock.now()) != 0,
                    timeout=20_000)
    sim.mute()  # the controller stops answering (it still obeys commands)
    assert wait_finished(qtbot, window) == RunState.FAILED
    box = window.last_message
    assert box is not None and box.isVisible()
    # in the scientist's words with the next action; the wire detail in the log pane only
    assert "InstrumentTimeout" not in box.text()
    assert "stage controller did not answer in time" in box.text()
    assert "Disconnect and Connect" in box.text()
    assert "InstrumentTimeout" in window.log.toPlainText()
    assert "InstrumentTimeout" not in window.statusBar().currentMessage()
    assert "STOP SENT, NOT CONFIRMED: stage unreachable" in box.text()  # the truth, no more
    # the controller is silent: not monitoring, and the fault's trip stays until acknowledged
    assert window.banner.state == "silent" and "KDC101 silent" in window.banner.text()
    assert "TRIPPED, not acknowledged: fault" in window.banner.text()
    assert "InstrumentTimeout" not in window.banner.text()
    assert sim.velocity_at(clock.now()) == 0.0
    t = clock.now()
    qtbot.wait(200)
    assert sim.position_at(clock.now()) == sim.position_at(t)  # and it stays stopped
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "failed" and meta["faults"]


def test_manual_control_homes_moves_and_stops(qtbot, open_window, monkeypatch):
    window = open_window(10.0)
    confirm_moves(monkeypatch)
    sim, clock = stage_sim(window), window.desk.clock
    manual = window.manual
    home(qtbot, window)
    manual.entries["speed"].setValue(2.0)
    manual.entries["target"].setValue(0.2)
    manual.buttons["move_to"].click()
    qtbot.waitUntil(lambda: window.instruments.values["position_m"].text() == "200 µm",
                    timeout=10_000)
    manual.entries["speed"].setValue(0.5)
    manual.entries["target"].setValue(10.0)
    manual.buttons["move_to"].click()
    qtbot.waitUntil(lambda: sim.velocity_at(clock.now()) > 0, timeout=5_000)
    window.stop_button.click()
    qtbot.waitUntil(lambda: sim.velocity_at(clock.now()) == 0.0, timeout=5_000)
    assert sim.position_at(clock.now()) < 5e-3
    manual.buttons["tare"].click()
    qtbot.waitUntil(lambda: "load-cell tare" in window.log.toPlainText(), timeout=5_000)


def test_screenshot_of_the_main_window_mid_run(qtbot, open_window, tmp_path):
    window = open_window(100.0)
    window.protocol.set_table(short_compression(hold="300 s", confirm=0), "<test>")
    window.protocol.run_button.click()
    qtbot.waitUntil(lambda: samples_in(window, 1) > 3000, timeout=30_000)

    def hold_drawn():  # the plot timer has drawn the hold curve (not merely buffered it)
        curve = {c.name(): c for c in window.plots.force_t.listDataItems()}.get(
            "1. ramp and hold")
        return curve is not None and curve.xData is not None and curve.xData.size > 1000

    qtbot.waitUntil(hold_drawn, timeout=10_000)
    qtbot.wait(100)
    assert window.desk.running
    path = tmp_path / "main-window-mid-run.png"
    assert window.grab().save(str(path))
    image = QImage(str(path))
    area = window.screen().availableGeometry()  # the window is sized to the screen
    assert (image.width(), image.height()) == (window.width(), window.height())
    assert image.width() <= area.width() and image.height() <= area.height()
    plot = window.plots.plots[0]
    corner = plot.mapTo(window, plot.rect().topLeft())
    region = image.copy(corner.x(), corner.y(), plot.width(), plot.height())
    region = region.convertToFormat(QImage.Format.Format_RGB32)
    pixels = np.frombuffer(region.constBits(), np.uint32)[: region.width() * region.height()]
    assert np.unique(pixels).size > 5  # axes, text and curves: not a blank or uniform plot
    hold_colour = QColor(colour(1)).rgb()  # the ramp-and-hold curve is drawn
    assert np.count_nonzero(pixels == np.uint32(hold_colour)) > 100


def test_closing_mid_run_asks_then_aborts_and_keeps_the_data(qtbot, open_window, monkeypatch):
    window = open_window(100.0)
    window.protocol.set_table(short_compression(hold="300 s", confirm=0), "<test>")
    window.protocol.run_button.click()
    qtbot.waitUntil(lambda: samples_in(window, 1) > 1000, timeout=30_000)
    sim, clock = stage_sim(window), window.desk.clock
    asked = []

    def answer(key):
        def ask(parent, title, text, on_answer, *args, **kwargs):
            asked.append(text)
            on_answer(key)
        return ask

    monkeypatch.setattr(dialogs, "ask", answer("no"))
    assert not window.close()
    assert window.desk.running and window.isVisible()
    monkeypatch.setattr(dialogs, "ask", answer("yes"))
    window.close()
    qtbot.waitUntil(lambda: not window.isVisible(), timeout=20_000)
    assert len(asked) == 2 and "kept" in asked[0]
    assert window.desk.rig is None  # closed, after the run ended
    assert sim.velocity_at(clock.now()) == 0.0
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "aborted" and "closed" in meta["reason"]
    with h5py.File(window.desk.run_path / meta["steps"][1]["file"]) as f:
        assert f["force_N"].size == meta["steps"][1]["samples"] > 1000


def test_shear_passes_are_overlaid_by_speed_and_direction(qtbot, open_window):
    window = open_window(math.inf, rig="shear")
    assert isinstance(window.plots, ShearPlots)
    window.protocol.set_table({"protocol": {"name": "ladder", "rig": "shear"}, "step": [
        {"kind": "speed_ladder", "overlaps": 1, "first_overlap": "0.4 mm",
         "speeds": ["1e-4 m/s", "2e-4 m/s"], "travel": "4 mm", "wait": "1 s",
         "interval": "0.05 s", "read_period": "0.5 s", "touch_gap": "3 mm",
         "centre_angle": 0.8}]}, "<test>")
    assert window.protocol.run_button.isEnabled(), window.protocol.why_not
    window.protocol.run_button.click()
    assert wait_finished(qtbot, window) == RunState.COMPLETED
    plots = window.plots
    assert plots.pass_count() == 4  # 2 speeds x (clockwise, back)
    curves = plots.f_h.listDataItems()
    assert len(curves) == 4 and all(c.xData.size > 10 for c in curves)
    styles = {(c.opts["pen"].color().name(), c.opts["pen"].style()) for c in curves}
    assert len(styles) == 4  # colour: speed; line style: direction
    legend = [label for _colour, _style, label in plots.legend_entries if "step" not in label]
    assert sorted(legend) == ["100 µm/s ccw", "100 µm/s cw", "200 µm/s ccw", "200 µm/s cw"]
    peak = max(float(np.max(c.yData)) for c in plots.f_v.listDataItems())
    assert peak > 0.0  # the spheres pushed each other apart during the passes


def test_readouts_follow_the_rig_and_time_runs_at_max_pace_when_idle(qtbot, open_window):
    window = open_window(math.inf)
    clock = window.desk.clock
    t0 = clock.now()
    qtbot.waitUntil(lambda: window.instruments.values["force_N"].text() != "-", timeout=5_000)
    time.sleep(0.3)
    qtbot.waitUntil(lambda: clock.now() > t0 + 0.2, timeout=5_000)
    assert "force" in window.banner.text() and "2 N" in window.banner.text()


def test_the_dry_run_rehearses_on_the_twin_and_a_failed_rehearsal_disables_run(qtbot,
                                                                               open_window):
    window = open_window()
    panel = window.protocol
    panel.set_table(short_compression(hold="2 s", confirm=0), "<test>")
    qtbot.waitUntil(lambda: panel.rehearsal is not None or bool(panel.rehearsal_error),
                    timeout=60_000)
    assert not panel.rehearsal_error
    assert panel.rehearsal.ok
    text = panel.plan_text.toPlainText()
    assert "Rehearsal on the rig's twin" in text and "rehearsal passed" in text
    assert panel.run_button.isEnabled()
    assert panel.status.text().startswith("ready: rehearsed on the rig's twin, ")
    # the static limit checks pass, the rehearsal does not: no first touch for the hold
    panel.set_table({"protocol": {"name": "hold only", "rig": "compression"},
                     "step": [{"kind": "ramp_hold", "diameter": "18.63 mm",
                               "hold": "2 s"}]}, "<test>")
    assert "rehearsing..." in panel.plan_text.toPlainText()
    qtbot.waitUntil(lambda: panel.rehearsal is not None or bool(panel.rehearsal_error),
                    timeout=60_000)
    assert not panel.rehearsal.ok
    assert not panel.run_button.isEnabled()
    assert "rehearsal failed" in panel.why_not and "first_touch" in panel.why_not
