"""Who ran a run and why, from the window (issue 28, item 1; ADR 0370): the operator, note and
tags fields above Run go into run.json as ``gelrig run --operator --note --tag`` puts them,
the catalog lists the run by them, a bad value keeps Run disabled with the CLI's one line,
and the fields are remembered in a new window."""

import contextlib
import json
import math
import sqlite3

from gelrig.catalog import find_runs
from gelrig.instrument.core.catalog import CATALOG_NAME
from tests.gui import test_app

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig


def test_the_fields_are_recorded_in_run_json_and_the_catalog(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    panel = window.protocol
    fields = panel.info_form
    fields.edits["operator"].setText("ada")
    fields.edits["note"].setText("fresh batch, cured 2 h")
    fields.edits["tags"].setText("week48, fast ,, week48")
    panel.set_table(test_app.short_compression(hold="2 s"), "<test>")
    qtbot.waitUntil(panel.run_button.isEnabled, timeout=60_000)
    panel.run_button.click()
    test_app.wait_finished(qtbot, window, timeout=60_000)
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "completed"
    index = tmp_path / "runs" / CATALOG_NAME  # written by the run host as the run ended
    with contextlib.closing(sqlite3.connect(index)) as con:
        row = con.execute("SELECT operator, note, status FROM runs WHERE name = ?",
                          (window.desk.run_path.name,)).fetchone()
        tags = [t for (t,) in con.execute("SELECT tag FROM tags")]
    assert row == ("ada", "fresh batch, cured 2 h", "completed") and tags == ["week48", "fast"]
    assert (meta["operator"], meta["note"], meta["tags"]) == (
        "ada", "fresh batch, cured 2 h", ["week48", "fast"])
    assert meta["finished_wall"]  # the host's teardown wrote it, as for a CLI run
    listed = find_runs(tmp_path / "runs", operator="ada", tag="fast")
    assert [e["path"] for e in listed] == [str(window.desk.run_path)]
    assert listed[0]["status"] == "completed" and listed[0]["note"] == "fresh batch, cured 2 h"


def test_a_bad_value_keeps_run_disabled_with_the_clis_line(qtbot, open_window):
    window = open_window(math.inf)
    panel = window.protocol
    panel.set_table(test_app.short_compression(hold="2 s"), "<test>")
    qtbot.waitUntil(panel.run_button.isEnabled, timeout=60_000)
    panel.info_form.edits["operator"].setText("x" * 101)
    assert panel.info_form.info is None
    assert not panel.run_button.isEnabled()
    assert "operator" in panel.why_not and "at most 100 characters" in panel.why_not
    assert panel.info_form.error.isVisibleTo(panel.info_form)
    panel.info_form.edits["operator"].setText("ada")
    qtbot.waitUntil(panel.run_button.isEnabled, timeout=60_000)
    assert not panel.info_form.error.isVisibleTo(panel.info_form)


def test_the_fields_are_remembered_in_a_new_window(qtbot, open_window):
    window = open_window(math.inf)
    window.protocol.info_form.set_texts({"operator": "bo", "note": "n1", "tags": "a, b"})
    window._leave_loaded = True
    window.close()
    again = open_window(math.inf)
    assert again.protocol.info_form.texts() == {"operator": "bo", "note": "n1", "tags": "a, b"}
    assert again.protocol.info_form.info.tags == ("a", "b")
