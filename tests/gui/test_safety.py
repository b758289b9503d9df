"""The GUI's safety and truthfulness (issue 15), driven through its buttons (pytest-qt,
offscreen): manual motions under the interlocks, the banner's true state with Acknowledge,
the loaded sample and its unload, the hold that can be ended but not paused, errors in the
scientist's words, and the emergency end of a run stuck in an instrument call."""

import dataclasses
import json
import math

import pytest

from gelrig.commands.gui import make_services
from gelrig.gui import dialogs
from gelrig.gui.mainwindow import MainWindow
from gelrig.gui.messages import REPLIES
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import default_rig
from tests.doubles import compression_rig
from tests.gui.test_app import (
    home,
    open_window,
    samples_in,
    short_compression,
    stage_sim,
    wait_finished,
)

__all__ = ["open_window"]  # the fixture, shared with test_app


def answer(monkeypatch, key, asked=None):
    """Answer every (non-modal) question at once with ``key`` ("yes", "no", "unload"...),
    recording the questions in ``asked``."""
    def ask(parent, title, text, on_answer, choices=dialogs.YES_NO, default="no"):
        if asked is not None:
            asked.append(text)
        on_answer(key)
    monkeypatch.setattr(dialogs, "ask", ask)


def move_to(window, mm, speed=0.5):
    window.manual.entries["speed"].setValue(speed)
    window.manual.entries["target"].setValue(mm)
    window.manual.buttons["move_to"].click()


@pytest.fixture
def soft_limit_window(qtbot, tmp_path):
    """A window on the built-in simulated compression rig with a 0.5 N force limit (a move
    to the end of travel, 5.8 mm past first touch, reaches about 0.9 N)."""
    text = default_rig("compression").read_text()
    assert 'max_force = "2 N"' in text
    path = tmp_path / "soft.toml"
    path.write_text(text.replace('max_force = "2 N"', 'max_force = "0.5 N"'))
    window = MainWindow(make_services(path, 10.0, tmp_path / "runs"))
    window.show()
    window.start()
    qtbot.waitUntil(lambda: window.desk.rig is not None, timeout=20_000)
    yield window
    window._leave_loaded = True  # teardown: close without asking about the sample
    window.close()


def test_a_manual_move_into_the_sphere_trips_the_force_interlock_and_stops(
        qtbot, soft_limit_window, monkeypatch):
    window = soft_limit_window
    session, banner = window.desk, window.banner
    limit = session.rig.limits.max_force
    touch = session.spec.table["simulator"]["first_touch"]
    ended = []
    session.motion_ended.connect(ended.append)
    home(qtbot, window)
    assert banner.state == "armed" and "every manual motion" in banner.text()
    assert "overlap ≤ 2.5 mm NOT ARMED (first touch unknown" in banner.text()
    answer(monkeypatch, "yes")  # before a contact search: confirmed, at most 0.3 mm/s
    speed = 0.3e-3
    move_to(window, 12.0, speed=speed * 1e3)  # the end of travel, deep into the sphere
    qtbot.waitUntil(lambda: banner.state == "tripped", timeout=60_000)
    sim, clock = stage_sim(window), session.clock
    qtbot.waitUntil(lambda: sim.velocity_at(clock.now()) == 0.0, timeout=5_000)
    trip = ended[-1].trip
    assert ended[-1].outcome == "tripped" and trip is not None
    # Stopped within one sample: the tripping sample is past the limit by at most one
    # sample's rise (Hertz: dF/dz = 1.5 F / overlap), give or take the noise (0.2 mN).
    z = sim.position_at(clock.now())
    overlap = z - float(touch.split()[0]) * 1e-3
    rise = 1.5 * limit / overlap * speed / 100.0  # per sample at 100 Hz
    assert 0 < trip.value - limit < rise + 3 * 0.2e-3, (trip.value, rise)
    assert z < 12e-3 - 1e-3  # at rest far short of the target
    assert banner.text().count("interlock force") == 1  # no repeated prefix
    assert "beyond the limit" in banner.text()
    qtbot.waitUntil(lambda: "now: force" in banner.text(), timeout=5_000)  # live, tripped
    assert banner.ack_button.isVisible()

    # re-arming is refused while the force is beyond the limit, and says why
    qtbot.waitUntil(lambda: not session.moving_by_hand and bool(session.loaded), timeout=5_000)
    banner.ack_button.click()
    assert banner.state == "tripped" and "cannot re-arm yet" in banner.text()
    # a move toward the sample is refused until acknowledged; nothing moves
    move_to(window, 11.0)
    qtbot.waitUntil(lambda: window.last_message is not None
                    and "acknowledge" in window.last_message.text().lower(), timeout=5_000)
    qtbot.wait(200)
    assert sim.position_at(clock.now()) == z

    # the sample shows as loaded and unloads to the safe position
    qtbot.waitUntil(lambda: banner.unload_button.isVisible(), timeout=5_000)
    assert "Sample loaded" in banner.sample_label.text()
    banner.unload_button.click()
    qtbot.waitUntil(lambda: "unload: " in window.log.toPlainText(), timeout=30_000)
    qtbot.waitUntil(lambda: not session.loaded, timeout=5_000)
    assert sim.position_at(clock.now()) < z
    banner.ack_button.click()
    assert banner.state == "armed" and not banner.ack_button.isVisible()


def test_a_move_before_homing_asks_to_home_first(qtbot, open_window, monkeypatch):
    window = open_window(10.0)
    sim, clock = stage_sim(window), window.desk.clock
    qtbot.waitUntil(lambda: window.instruments.values["homed"].text() == "no", timeout=5_000)
    z = sim.position_at(clock.now())
    asked = []
    answer(monkeypatch, "no", asked)
    move_to(window, 4.0)
    assert len(asked) == 1 and "not homed" in asked[0]
    qtbot.wait(300)
    assert sim.position_at(clock.now()) == z  # nothing moved
    answer(monkeypatch, "yes", asked)
    move_to(window, 4.0)
    qtbot.waitUntil(lambda: window.instruments.values["homed"].text() == "yes", timeout=15_000)
    assert len(asked) == 2 and "stage home" in window.log.toPlainText()


def test_the_banner_does_not_monitor_when_disconnected_or_never_connected(qtbot, open_window,
                                                                         tmp_path):
    window = open_window(math.inf)
    banner = window.banner
    qtbot.waitUntil(lambda: "now: force" in banner.text(), timeout=5_000)
    window.instruments.disconnect_button.click()
    qtbot.waitUntil(lambda: window.desk.rig is None and banner.state == "off",
                    timeout=10_000)
    assert "NOT MONITORING" in banner.text() and "now:" not in banner.text()
    qtbot.waitUntil(lambda: window.statusBar().currentMessage() == "disconnected",
                    timeout=10_000)
    assert window.header.readout.text() == "" == window.header.stale.text()

    base = make_services(default_rig("compression"), math.inf, tmp_path / "runs")

    def refuse(spec, clock):
        raise ConnectionRefusedError(111, "Connection refused")

    broken = MainWindow(dataclasses.replace(base, build_rig=refuse))
    try:
        broken.start()
        qtbot.waitUntil(lambda: broken.instruments.state_label.text() == "connection failed",
                        timeout=10_000)
        assert broken.banner.state == "off" and "NOT MONITORING" in broken.banner.text()
        assert "starting" not in broken.statusBar().currentMessage()
        assert "connection failed" in broken.statusBar().currentMessage()
        box = broken.last_message
        assert box is not None and "address" in box.text()  # what to check, not errno
        qtbot.waitUntil(lambda: "ConnectionRefusedError" in broken.log.toPlainText(),
                        timeout=5_000)  # the detail: the log pane
    finally:
        broken.close()


def holding(qtbot, open_window, pace=100.0):
    """A window whose run holds the sample (a 3000 s hold)."""
    window = open_window(pace)
    window.protocol.set_table(short_compression(hold="3000 s", confirm=0), "<test>")
    window.protocol.run_button.click()
    qtbot.waitUntil(lambda: window.desk.holding, timeout=60_000)
    return window


def test_pause_during_a_hold_offers_to_end_it_and_the_run_goes_on(qtbot, open_window):
    window = holding(qtbot, open_window)
    panel = window.protocol
    assert not panel.resume_button.isEnabled()  # not paused: nothing to resume
    qtbot.waitUntil(lambda: samples_in(window, 1) > 20_000, timeout=60_000)  # 1 kHz
    offered = []
    panel.ask_hold = lambda choose: offered.append(True) or choose("end")
    panel.pause_button.click()
    assert offered and "ending the hold now" in panel.status.text()
    assert wait_finished(qtbot, window, timeout=60_000) == RunState.COMPLETED
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    hold = meta["steps"][1]
    assert hold["status"] == "completed" and 0 < hold["results"]["held_s"] < 3000
    assert hold["samples"] > 1000  # its data kept
    assert "ending the hold now" in window.log.toPlainText()
    assert not panel.resume_button.isEnabled()


def test_pause_during_a_hold_can_abort(qtbot, open_window):
    window = holding(qtbot, open_window)
    panel = window.protocol
    panel.ask_hold = lambda choose: choose("abort")
    panel.pause_button.click()
    assert wait_finished(qtbot, window, timeout=30_000) == RunState.ABORTED
    assert "pause requested" not in panel.status.text()


def test_a_loaded_sample_makes_run_and_disconnect_ask(qtbot, open_window, monkeypatch):
    window = open_window(10.0)
    home(qtbot, window)
    answer(monkeypatch, "yes")  # before a contact search: confirmed
    move_to(window, 6.4)  # 0.2 mm into the sphere: loaded, within the limits
    qtbot.waitUntil(lambda: bool(window.desk.loaded) and not window.desk.moving_by_hand,
                    timeout=30_000)
    assert window.banner.unload_button.isVisible()
    asked = []
    answer(monkeypatch, "no", asked)
    window.protocol.set_table(short_compression(), "<test>")
    window.protocol.run_button.click()
    assert len(asked) == 1 and "loaded" in asked[0]
    assert not window.desk.running
    window.instruments.disconnect_button.click()
    assert len(asked) == 2 and window.desk.rig is not None


def test_errors_read_in_the_scientists_words_with_the_detail_in_the_log(qtbot, open_window):
    window = open_window(math.inf, rig="shear")
    qtbot.waitUntil(lambda: window.instruments.values["gap_referenced"].text() == "no",
                    timeout=5_000)
    window.manual.buttons["set_gap"].click()  # before the gap is referenced
    qtbot.waitUntil(lambda: window.last_message is not None, timeout=10_000)
    text = window.last_message.text()
    assert REPLIES[("MCR 501", 12)] in text and "DeviceErrorReply" not in text
    qtbot.waitUntil(lambda: "error 12" in window.log.toPlainText(),  # the wire detail
                    timeout=5_000)


@pytest.fixture
def fake_window(qtbot, tmp_path):
    """A window on a compression rig of freezable fakes (tests/doubles.py)."""
    base = make_services(default_rig("compression"), math.inf, tmp_path / "runs")
    rig, stage, force = compression_rig()
    window = MainWindow(dataclasses.replace(base, build_rig=lambda spec, clock: rig))
    window.fakes = (rig, stage, force)
    window.show()
    window.start()
    qtbot.waitUntil(lambda: window.desk.rig is not None, timeout=10_000)
    yield window
    stage.faults.thaw()
    force.faults.thaw()
    window._leave_loaded = True
    window.close()
    if window.isVisible():
        window.desk.shutdown(5.0)


def test_stop_twice_ends_a_stuck_run_from_outside_with_a_verified_safe_stop(qtbot,
                                                                            fake_window):
    window = fake_window
    _rig, stage, force = window.fakes
    window.protocol.set_table(short_compression(hold="3000 s"), "<test>")
    window.protocol.run_button.click()
    qtbot.waitUntil(lambda: window.desk.data.samples() > 0, timeout=60_000)  # loaded CI
    force.faults.freeze()  # the run blocks in a force read that ignores its deadline
    qtbot.waitUntil(force.faults.blocked.is_set, timeout=10_000)
    window.stop_button.click()
    qtbot.wait(200)
    assert window.desk.running  # one press: the abort waits for the run
    window.stop_button.click()
    qtbot.waitUntil(lambda: not window.desk.running, timeout=30_000)
    assert force.faults.blocked.is_set()  # the run thread is still stuck
    assert window.protocol.state == RunState.ABORTED
    box = window.last_message
    assert box is not None and "motion stopped (verified)" in box.text()
    assert not stage.is_moving()
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "aborted" and meta["safe_state"]["verified"]
    assert "stuck" in meta["reason"]
    # the rig thread is still stuck: not monitoring, and the trip stays until acknowledged
    assert window.banner.state == "silent", window.banner.text()
    assert "stuck in an instrument call" in window.banner.text()
    assert "TRIPPED, not acknowledged" in window.banner.text()


def test_a_manual_rotation_is_watched_with_live_values_and_stop_ends_it(qtbot, open_window):
    window = open_window(10.0, rig="shear")
    session, manual = window.desk, window.manual
    manual.buttons["zero_gap"].click()
    qtbot.waitUntil(lambda: window.instruments.values["gap_referenced"].text() == "yes",
                    timeout=15_000)
    manual.entries["speed"].setValue(0.5)
    manual.buttons["rotate"].click()
    qtbot.waitUntil(lambda: session.moving_by_hand, timeout=5_000)
    angle = window.instruments.values["angle_rad"].text()
    qtbot.waitUntil(lambda: window.instruments.values["angle_rad"].text() != angle,
                    timeout=10_000)  # live values while the rig thread watches the motion
    assert session.moving_by_hand  # a rotation does not end by itself
    ended = []
    session.motion_ended.connect(ended.append)
    window.stop_button.click()
    qtbot.waitUntil(lambda: bool(ended), timeout=10_000)
    assert ended[0].outcome == "stopped"
    qtbot.waitUntil(lambda: window.instruments.values["moving"].text() == "at rest",
                    timeout=10_000)


def test_closing_during_a_stuck_run_ends_it_from_outside_and_closes(qtbot, fake_window,
                                                                    monkeypatch):
    window = fake_window
    _rig, stage, force = window.fakes
    window.protocol.set_table(short_compression(hold="3000 s"), "<test>")
    window.protocol.run_button.click()
    qtbot.waitUntil(lambda: window.desk.data.samples() > 0, timeout=60_000)  # loaded CI
    force.faults.freeze()
    qtbot.waitUntil(force.faults.blocked.is_set, timeout=10_000)
    answer(monkeypatch, "yes")
    window.close()  # asks, aborts; the run does not answer; closing ends it from outside
    qtbot.waitUntil(lambda: not window.isVisible(), timeout=30_000)
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "aborted" and meta["safe_state"]["verified"]
    assert not stage.is_moving()
