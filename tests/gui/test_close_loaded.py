"""Closing or quitting with the sample loaded asks first (issue 25, item 2): Unload and
close / Close leaving it loaded / Cancel, in a non-modal question (STOP stays in reach)."""

from PySide6.QtWidgets import QApplication, QMessageBox

from tests.gui.test_app import home, open_window, stage_sim
from tests.gui.test_safety import answer, move_to

__all__ = ["open_window"]


def loaded_window(qtbot, open_window, monkeypatch):
    window = open_window(10.0)
    home(qtbot, window)
    answer(monkeypatch, "yes")  # the move before a contact search, confirmed
    move_to(window, 6.5, speed=0.3)  # 0.3 mm into the sphere (first touch at 6.2 mm)
    qtbot.waitUntil(lambda: bool(window.desk.loaded) and not window.desk.moving_by_hand,
                    timeout=60_000)
    monkeypatch.undo()  # the closing question is answered by its buttons below
    return window


def closing_question():
    return next(w for w in QApplication.topLevelWidgets()
                if isinstance(w, QMessageBox) and w.isVisible()
                and w.windowTitle() == "The sample is loaded")


def click(box, text):
    next(b for b in box.buttons() if b.text() == text).click()


def test_closing_with_the_sample_loaded_asks_and_cancel_keeps_the_window(
        qtbot, open_window, monkeypatch):
    window = loaded_window(qtbot, open_window, monkeypatch)
    assert not window.close()
    box = closing_question()
    assert not box.isModal()
    assert {b.text() for b in box.buttons()} == {"Unload and close", "Close leaving it loaded",
                                                 "Cancel"}
    assert "mN on the sample" in box.text() or "past first touch" in box.text()
    click(box, "Cancel")
    qtbot.wait(200)
    assert window.isVisible() and window.desk.rig is not None
    assert not window.close()  # asks again
    click(closing_question(), "Close leaving it loaded")
    qtbot.waitUntil(lambda: not window.isVisible(), timeout=20_000)
    assert "closing with the sample loaded" in window.log.toPlainText()


def test_unload_and_close_retracts_the_plate_then_closes(qtbot, open_window, monkeypatch):
    window = loaded_window(qtbot, open_window, monkeypatch)
    sim, clock = stage_sim(window), window.desk.clock
    window.close()
    click(closing_question(), "Unload and close")
    qtbot.waitUntil(lambda: not window.isVisible(), timeout=60_000)
    assert sim.position_at(clock.now()) < 6.2e-3  # clear of the sphere
    assert sim.velocity_at(clock.now()) == 0.0
    assert "unload: motion stopped (verified)" in window.log.toPlainText()
