"""Work off the GUI thread: no worker ever drops the last reference to what the GUI thread
owns (ADR 0395). A Qt object destroyed on a worker deadlocks against the GUI thread; the
sentinel here is a plain object that says on which thread it was let go of."""

import gc
import threading

import pytest
from PySide6.QtCore import QObject

from gelrig.gui import offthread
from gelrig.gui.tasks import RigThread


class Sentinel:
    """Records the thread that drops the last reference to it."""

    def __init__(self, record: list[str]):
        self.record = record

    def __del__(self):
        self.record.append(threading.current_thread().name)


def test_work_holding_a_qt_object_is_refused_with_what_it_holds(qtbot):
    owner = QObject()

    def holds_it():
        return owner.objectName()

    with pytest.raises(TypeError, match="QObject"):
        offthread.start(holds_it, lambda _value: None, name="refused")
    with pytest.raises(TypeError, match="QObject"):
        offthread.start(owner.objectName, lambda _value: None, name="refused")
    assert offthread.qt_objects_held(lambda: 1) == []


def test_a_result_and_an_error_reach_done_on_the_gui_thread_and_die_there(qtbot):
    record: list[str] = []
    got: list[object] = []
    seen: list[str] = []

    def done(value):
        seen.append(threading.current_thread().name)
        got.append(type(value).__name__)

    offthread.start(lambda: Sentinel(record), done, name="worker-a")

    def fails():
        raise ValueError("the step file is damaged")

    offthread.start(fails, done, name="worker-b")
    qtbot.waitUntil(lambda: len(got) == 2, timeout=5_000)
    gc.collect()
    assert sorted(got) == ["Sentinel", "ValueError"]
    assert seen == [threading.main_thread().name] * 2
    assert record == [threading.main_thread().name]


def test_a_result_for_a_deleted_owner_is_dropped(qtbot):
    class Owner(QObject):
        def take(self, value):
            raise AssertionError("delivered to a deleted object")

    owner = Owner()
    release = threading.Event()
    offthread.start(lambda: release.wait(5), owner.take, name="late")
    owner.deleteLater()
    qtbot.waitUntil(lambda: not offthread.shiboken6.isValid(owner), timeout=5_000)
    release.set()
    qtbot.wait(200)  # the late result arrives and is dropped, not raised


def test_a_rig_task_and_its_result_are_let_go_of_on_the_gui_thread(qtbot):
    """The task's closure (in the GUI, a window) and its result die on the GUI thread,
    even when the GUI side has dropped everything else it held."""
    record: list[str] = []
    worker = RigThread()
    results: list[str] = []
    captured = Sentinel(record)

    def task(held=captured):
        return Sentinel(record)

    doomed = Sentinel(record)

    def failing(held=doomed):
        raise RuntimeError("the stage did not answer")

    assert worker.submit(task, done=lambda value: results.append(type(value).__name__))
    assert worker.submit(failing, failed=lambda exc: results.append(str(exc)))
    del task, failing, captured, doomed
    qtbot.waitUntil(lambda: len(results) == 2, timeout=5_000)
    qtbot.waitUntil(lambda: worker.idle, timeout=5_000)
    assert worker.submit(lambda: None)  # its delivery lets go of the finished tasks
    qtbot.waitUntil(lambda: len(record) == 3, timeout=5_000)
    gc.collect()
    assert results == ["Sentinel", "the stage did not answer"]
    assert record == [threading.main_thread().name] * 3
    assert worker.shutdown(5)
