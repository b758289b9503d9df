"""The Queue tab (issue 28, item 6; ADR 0371): queued protocols run one after another on the
simulated rig in virtual time, each rehearsed on the rig's twin before it starts; the queue
stops at the first item that does not complete and says why; a sweep over one parameter is
one item per value; the queue is kept across windows, and a corrupt queue file is set aside
with one warning."""

import json
import math

import pytest

from gelrig.gui.mainwindow import queue_file
from gelrig.gui.queue_items import COMPLETED, QUEUED, STOPPED, QueueItem
from tests.gui import test_app
from tests.gui.test_sample_fields import toml_text

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig


def protocol_file(tmp_path, hold="1 s"):
    path = tmp_path / "hold.toml"
    path.write_text(toml_text(test_app.short_compression(hold=hold)))
    return path


def counted(window):
    """Count the rehearsals the queue asks for (the real ones, on the rig's twin)."""
    calls = []
    rehearser = window.queue_runner.rehearser

    def counting():
        rehearse = rehearser()

        def run(procedure, control):
            calls.append(procedure)
            return rehearse(procedure, control)

        return run

    window.queue_runner.rehearser = counting
    return calls


def queue_sweep(window, path, name, values):
    window.protocol.load_file(path)
    window.queue.param.setText(name)
    window.queue.values.setText(values)
    return window.queue.add_current()


def wait_queue(qtbot, window, timeout=120_000):
    qtbot.waitUntil(lambda: not window.queue_runner.active and not window.desk.running,
                    timeout=timeout)


def test_a_sweep_expands_into_one_item_per_value(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    path = protocol_file(tmp_path)
    window.protocol.info_form.edits["operator"].setText("ada")
    items = queue_sweep(window, path, "step[1].hold", "10 s; 20 s; 30 s")
    assert [i.params for i in items] == [{"step[1].hold": v} for v in ("10 s", "20 s", "30 s")]
    assert [i.state for i in window.queue_runner.items] == [QUEUED] * 3
    assert window.queue.list.count() == 3
    assert window.queue.list.item(2).text() == "3. [queued] hold.toml  step[1].hold=30 s"
    assert all(i.operator == "ada" for i in items)
    assert [p.steps[1].params.hold for p in (i.procedure() for i in items)] == [10, 20, 30]
    window.queue.values.setText("10 s; -1 s")  # a bad value: said now, nothing queued
    assert window.queue.add_current() == []
    assert "hold" in window.queue.status.text() and len(window.queue_runner.items) == 3


def test_a_two_item_queue_runs_both_each_rehearsed_first(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    calls = counted(window)
    window.protocol.info_form.edits["tags"].setText("queued")
    queue_sweep(window, protocol_file(tmp_path), "step[1].hold", "1 s; 2 s")
    window.show_tab("left", 3)
    window.queue.start_button.click()
    wait_queue(qtbot, window)
    assert window.left_tabs.currentIndex() == 3  # the queue stayed in view
    assert window.protocol.run_plan is None  # the queued run's plan, dropped at its end
    items = window.queue_runner.items
    assert [i.state for i in items] == [COMPLETED, COMPLETED], [i.reason for i in items]
    assert len(calls) == 2 and [p.steps[1].params.hold for p in calls] == [1, 2]
    metas = [json.loads((tmp_path / "runs" / i.run / "run.json").read_text()) for i in items]
    assert [m["status"] for m in metas] == ["completed", "completed"]
    assert [m["steps"][1]["params"]["hold"] for m in metas] == [1, 2]
    assert [m["tags"] for m in metas] == [["queued"], ["queued"]]
    assert window.queue_runner.message == "queue done: 2 run(s) completed"
    assert window.queue.start_button.isEnabled() and not window.queue.stop_button.isEnabled()


def test_a_bad_item_stops_the_queue_with_its_reason(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    path = protocol_file(tmp_path)
    items = queue_sweep(window, path, "step[1].hold", "1 s; 2 s; 3 s")
    window.queue_runner.items[1].params["step[1].hold"] = "-5 s"  # as if the file was edited
    window.queue_runner.start()
    wait_queue(qtbot, window)
    assert [i.state for i in items] == [COMPLETED, STOPPED, QUEUED]
    reason = items[1].reason
    assert reason.startswith("not started: ") and "hold" in reason and "-5" in reason
    status = window.queue.status.text()
    assert status.startswith("queue stopped at item 2 (hold.toml  step[1].hold=-5 s): not "
                             "started:")
    assert status in window.log.toPlainText()
    runs = [p for p in (tmp_path / "runs").iterdir() if p.is_dir()]
    assert len(runs) == 1  # the third never started


def test_a_run_that_does_not_complete_stops_the_queue(qtbot, open_window, tmp_path):
    window = open_window(1.0)  # real pace: the run is still going when aborted
    items = queue_sweep(window, protocol_file(tmp_path, "60 s"), "step[1].hold", "60 s; 1 s")
    window.queue.start_button.click()
    qtbot.waitUntil(lambda: window.desk.running, timeout=60_000)
    window.abort()
    wait_queue(qtbot, window)
    assert [i.state for i in items] == [STOPPED, QUEUED]
    assert items[0].reason.startswith("run aborted: ")
    assert "queue stopped at item 1" in window.queue.status.text()
    assert len([p for p in (tmp_path / "runs").iterdir() if p.is_dir()]) == 1


def test_the_queue_survives_a_new_window_and_a_corrupt_file_is_set_aside(
        qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    window.protocol.info_form.edits["operator"].setText("bo")
    queue_sweep(window, protocol_file(tmp_path), "step[1].hold", "5 s, 6 s")
    window._leave_loaded = True
    window.close()
    again = open_window(math.inf)
    kept = again.queue_runner.items
    assert [(i.params, i.operator, i.state) for i in kept] == [
        ({"step[1].hold": "5 s"}, "bo", QUEUED), ({"step[1].hold": "6 s"}, "bo", QUEUED)]
    assert again.queue.list.count() == 2
    again._leave_loaded = True
    again.close()
    path = queue_file()
    path.write_text("{ not json")
    third = open_window(math.inf)
    assert third.queue_runner.items == [] and third.queue.list.count() == 0
    warnings = [line for line in third.log.toPlainText().splitlines() if "queue file" in line]
    assert len(warnings) == 1 and "set aside" in warnings[0]
    aside = list(path.parent.glob("gelrig-queue.json.corrupt-*"))
    assert len(aside) == 1 and aside[0].read_text() == "{ not json"


def test_closing_during_a_rehearsal_leaves_the_item_queued(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    queue_sweep(window, protocol_file(tmp_path), "step[1].hold", "1 s")
    window.queue.start_button.click()
    assert [i.state for i in window.queue_runner.items] == ["rehearsing"]
    window._leave_loaded = True
    window.close()  # before the rehearsal is collected: nothing started, nothing moved
    again = open_window(math.inf)
    assert [i.state for i in again.queue_runner.items] == [QUEUED]
    assert not (tmp_path / "runs").exists() or not [
        p for p in (tmp_path / "runs").iterdir() if (p / "run.json").exists()]


def test_a_script_that_no_longer_loads_stops_the_queue_without_a_traceback(
        qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    script = tmp_path / "broken.py"
    script.write_text("def protocol(:\n")
    window.queue_runner.add([QueueItem(str(script)), QueueItem(str(protocol_file(tmp_path)))])
    window.queue_runner.start()
    item, after = window.queue_runner.items
    assert (item.state, after.state) == (STOPPED, QUEUED)
    assert item.reason.startswith("not started: ") and "broken.py" in item.reason
    assert not window.queue_runner.active and window.queue.start_button.isEnabled()


@pytest.mark.slow
def test_a_script_sweep_runs_with_its_parameter_values(qtbot, open_window, tmp_path):
    from tests.gui.test_script_in_window import SCRIPT

    window = open_window(math.inf)
    path = tmp_path / "relax.py"
    path.write_text(SCRIPT)
    window.protocol.load_file(path)
    window.protocol.script_form.entries["hold"].setText('"1 s"')
    window.queue.param.setText("strain")
    window.queue.values.setText("0.01; 0.02")
    items = window.queue.add_current()
    assert [i.params for i in items] == [{"hold": '"1 s"', "strain": v} for v in ("0.01", "0.02")]
    window.queue_runner.start()
    wait_queue(qtbot, window)
    assert [i.state for i in items] == [COMPLETED, COMPLETED], [i.reason for i in items]
    ramps = [json.loads((tmp_path / "runs" / i.run / "run.json").read_text())["steps"][1]
             for i in items]
    assert [(r["params"]["strain"], r["params"]["hold"]) for r in ramps] == [(0.01, 1.0),
                                                                          (0.02, 1.0)]
