"""The window opens protocol scripts too (issue 25, item 6; docs/scripting.md): File > Open
takes a ``.py``, its function's parameters are fields holding TOML values, the plan is its
rehearsal on the rig's twin, and Run runs it with the values in the fields."""

import json
import math

from gelrig.gui.tomlout import value_text
from gelrig.protocols.events import RunState
from gelrig.protocols.script import Script
from tests.gui import test_app

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig

SCRIPT = '''
import gelrig


@gelrig.protocol(rig="compression", name="short relaxation", description="a test script")
def relax(run, strain=0.01, hold="20 s"):
    run.step("compression_contact_search", start="5 mm", confirm=1, tare_time="0.2 s")
    run.step("ramp_hold", strain=strain, strain_rate="0.01 /s", hold=hold, rate="1000 Hz",
             retract="0.5 mm", terms=1, diameter="18.63 mm")  # the simulated rig's sphere
'''


def test_a_script_opens_with_its_parameters_as_fields_and_runs_with_their_values(
        qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    assert "*.py" in " ".join(window.choose_protocol().nameFilters())
    path = tmp_path / "relax.py"
    path.write_text(SCRIPT)
    window._open_protocol(str(path))
    panel = window.protocol
    assert panel.is_script and str(path) in panel.file_label.text()
    entries = panel.script_form.entries
    assert list(entries) == ["strain", "hold"]
    assert [entries[k].text() for k in entries] == ["0.01", '"20 s"']
    assert "default 0.01" in entries["strain"].toolTip()
    entries["hold"].setText('"2 s"')
    spec = panel.spec
    assert isinstance(spec, Script) and dict(spec.params) == {"strain": 0.01, "hold": "2 s"}
    # the plan of a script is its rehearsal on the twin, with the values in the fields
    qtbot.waitUntil(lambda: panel.rehearsal is not None, timeout=60_000)
    assert panel.rehearsal.ok and "Rehearsal on the rig's twin" in panel.plan_text.toPlainText()
    assert "decides its steps as it runs" in panel.plan_text.toPlainText()
    qtbot.waitUntil(panel.run_button.isEnabled, timeout=10_000)
    panel.run_button.click()
    test_app.wait_finished(qtbot, window)
    assert window.desk.state is RunState.COMPLETED
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "completed"
    assert meta["protocol"]["protocol"]["params"] == {"strain": 0.01, "hold": "2 s"}
    assert [step["kind"] for step in meta["steps"]] == ["compression_contact_search",
                                                        "ramp_hold"]
    assert (window.desk.run_path / "script" / "relax.py").is_file()


def test_a_script_that_cannot_be_loaded_is_one_line_and_cannot_run(qtbot, open_window,
                                                                   tmp_path):
    window = open_window(math.inf)
    path = tmp_path / "broken.py"
    path.write_text("import gelrig\n\ndef relax(run:\n")
    window.protocol.load_file(path)
    panel = window.protocol
    assert panel.is_script and panel.spec is None
    assert "cannot be loaded as a script" in panel.script_form.message.text()
    assert not panel.run_button.isEnabled()
    assert panel.why_not.startswith("fix the protocol: ")
    # a protocol file again: the steps' form comes back
    panel.set_table(test_app.short_compression(), "<table>")
    assert not panel.is_script and panel.spec is not None


def test_an_empty_field_leaves_the_functions_default_and_a_value_reads_as_toml(
        qtbot, tmp_path):
    from gelrig.gui.script_form import ScriptForm
    from gelrig.protocols.script import load_script

    path = tmp_path / "relax.py"
    path.write_text(SCRIPT)
    form = ScriptForm()
    qtbot.addWidget(form)
    form.set_script(load_script(str(path)))
    form.entries["strain"].setText("")
    form.entries["hold"].setText("600 s")  # a bare word stays a string, as --param
    assert dict(form.script.params) == {"hold": "600 s"}
    form.entries["strain"].setText("[0.02, 0.04]")
    assert form.script.params["strain"] == [0.02, 0.04]
    assert form.entries["strain"].text() == value_text([0.02, 0.04])
