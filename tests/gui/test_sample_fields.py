"""The run's sample in the window (issue 27, item 1; docs/decisions/0280): the Sample fields
above Run replace the protocol file's ``[sample]``, a step takes its size from them, a run
without a size a step needs is refused before anything moves with the CLI's one line, the
fields are remembered per rig kind across windows, and Save writes them as ``[sample]``."""

import json
import math
import tomllib

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.spec import parse_protocol
from tests.gui import test_app
from tests.gui.test_refused_run import run_folders

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig


def ramp_hold_protocol():
    """A contact search, then a 4 % ramp with a short hold: the depth is 4 % of the sample's
    diameter (no diameter in the step, no [sample]: the window's fields give it)."""
    return {"protocol": {"name": "4 % of the sample", "rig": "compression"}, "step": [
        {"kind": "compression_contact_search", "start": "5 mm", "confirm": 0,
         "tare_time": "0.2 s"},
        {"kind": "ramp_hold", "strain": 0.04, "strain_rate": "0.01 /s", "hold": "2 s",
         "rate": "1000 Hz", "retract": "0.5 mm", "terms": 1}]}


def missing_line(table, source):
    """The one line gelrig plan and run give for this protocol without a sample."""
    with pytest.raises(ConfigError) as caught:
        parse_protocol(table, source)
    return str(caught.value)


def test_a_12_mm_sphere_in_the_fields_gives_a_048_mm_depth_recorded_in_run_json(
        qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    panel = window.protocol
    fields = panel.sample_form
    assert fields.edits["diameter"].isVisibleTo(fields)  # compression: the diameter
    assert not fields.edits["r1"].isVisibleTo(fields)
    tip = fields.edits["diameter"].toolTip()
    assert "diameter" in tip and "allowed (0, 100] mm" in tip
    path = tmp_path / "ramp.toml"
    path.write_text(toml_text(ramp_hold_protocol()))
    window.protocol.load_file(path)
    fields.edits["name"].setText("PDMS A3")
    fields.edits["diameter"].setText("12 mm")
    assert panel.spec is not None and panel.spec.sample.diameter == pytest.approx(0.012)
    assert "ramp 0.4800 mm" in panel.plan_text.toPlainText()
    qtbot.waitUntil(panel.run_button.isEnabled, timeout=60_000)
    panel.run_button.click()
    test_app.wait_finished(qtbot, window, timeout=60_000)
    meta = json.loads((window.desk.run_path / "run.json").read_text())
    assert meta["status"] == "completed"
    assert meta["sample"] == {"name": "PDMS A3", "diameter": pytest.approx(0.012)}
    assert meta["protocol"]["sample"] == {"name": "PDMS A3", "diameter": "12 mm"}
    ramp = meta["steps"][1]
    assert ramp["kind"] == "ramp_hold"
    assert ramp["params"]["diameter"] == pytest.approx(0.012)
    assert ramp["results"]["depth_m"] == pytest.approx(0.48e-3, rel=1e-9)


def test_without_a_diameter_the_run_is_refused_with_the_clis_line_and_no_folder(
        qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    panel = window.protocol
    path = tmp_path / "ramp.toml"
    table = ramp_hold_protocol()
    path.write_text(toml_text(table))
    panel.sample_form.edits["diameter"].setText("12 mm")
    panel.load_file(path)
    assert panel.spec is not None and not panel.refusal
    panel.sample_form.edits["diameter"].setText("")  # cleared
    line = missing_line(table, str(path))
    assert panel.spec is None and panel.refusal == line
    assert line.splitlines() == [line] and "the sample's diameter is needed" in line
    assert line in panel.plan_text.toPlainText()  # the plan says it too
    error = panel.sample_form.sizes["diameter"].error
    assert error.isVisibleTo(panel) and "takes it from the sample" in error.text()
    assert panel.run_button.isEnabled()
    panel.run_button.click()
    test_refused = window.last_message
    assert test_refused is not None and test_refused.windowTitle() == "Run refused"
    lines = test_refused.text().splitlines()
    assert lines[0] == line and "no run folder" in lines[-1]
    assert f"run refused: {line}; no run folder made" in window.log.toPlainText()
    assert not window.desk.running and window.desk.run_path is None
    assert run_folders(tmp_path) == []
    # a bad value is the field's own one line; Run is not offered
    panel.sample_form.edits["diameter"].setText("12 kg")
    assert panel.spec is None and not panel.refusal and not panel.run_button.isEnabled()
    assert error.isVisibleTo(panel) and error.text()
    panel.sample_form.edits["diameter"].setText("200 mm")
    assert error.text() == "allowed (0, 100] mm" and not panel.run_button.isEnabled()


def test_the_fields_are_remembered_per_rig_kind_in_a_new_window(qtbot, open_window):
    window = open_window(math.inf)
    fields = window.protocol.sample_form
    fields.edits["name"].setText("PDMS A3")
    fields.edits["diameter"].setText("12 mm")
    fields.edits["material"].setText("Sylgard 184, 10:1")
    fields.set_kind("shear")
    assert fields.edits["r1"].isVisibleTo(fields) and not fields.edits["diameter"].text()
    fields.edits["r1"].setText("9.2 mm")
    fields.edits["r2"].setText("9.96 mm")
    fields.set_kind("compression")
    window._leave_loaded = True
    window.close()
    again = open_window(math.inf)
    fields = again.protocol.sample_form
    assert fields.current() == {"name": "PDMS A3", "diameter": "12 mm",
                                "material": "Sylgard 184, 10:1"}
    fields.set_kind("shear")
    assert fields.current() == {"r1": "9.2 mm", "r2": "9.96 mm"}


def test_a_files_sample_fills_the_fields_and_save_writes_the_fields(qtbot, open_window,
                                                                     tmp_path):
    window = open_window(math.inf)
    panel = window.protocol
    table = ramp_hold_protocol()
    table["sample"] = {"name": "from the file", "diameter": "18.63 mm"}
    path = tmp_path / "ramp.toml"
    path.write_text(toml_text(table))
    panel.load_file(path)
    fields = panel.sample_form
    assert fields.edits["name"].text() == "from the file"
    assert fields.edits["diameter"].text() == "18.63 mm"
    assert not panel.modified
    fields.edits["diameter"].setText("12 mm")
    assert panel.modified  # Save would write the new sample
    assert panel.spec is not None and panel.spec.sample.diameter == pytest.approx(0.012)
    assert window.save_protocol() == path
    saved = tomllib.loads(path.read_text())
    assert saved["sample"] == {"name": "from the file", "diameter": "12 mm"}
    assert saved["step"] == table["step"] and not panel.modified
    # no sample in the fields: Save writes none
    fields.edits["name"].setText("")
    fields.edits["diameter"].setText("")
    window.save_protocol()
    assert "sample" not in tomllib.loads(path.read_text())


def toml_text(table):
    from gelrig.gui.tomlout import dumps

    return dumps(table)


SCRIPT = '''
import gelrig


@gelrig.protocol(rig="compression", name="4 % of the sample")
def relax(run, strain=0.04):
    run.step("compression_contact_search", start="5 mm", confirm=0, tare_time="0.2 s")
    run.step("ramp_hold", strain=strain, strain_rate="0.01 /s", hold="2 s", rate="1000 Hz",
             retract="0.5 mm", terms=1)
'''


def test_a_script_measures_the_sample_in_the_fields(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    panel = window.protocol
    path = tmp_path / "relax.py"
    path.write_text(SCRIPT)
    panel.sample_form.edits["diameter"].setText("12 mm")
    panel.load_file(path)
    assert panel.is_script and panel.spec.sample.diameter == pytest.approx(0.012)
    qtbot.waitUntil(lambda: panel.rehearsal is not None, timeout=60_000)
    assert panel.rehearsal.ok, panel.rehearsal.failure()
    uses = panel.rehearsal.steps[1].uses
    assert any(line.startswith("diameter = 12 mm") and "(sample)" in line for line in uses), uses
    # no diameter: the rehearsal refuses the ramp with the CLI's line, Run is not offered
    panel.sample_form.edits["diameter"].setText("")
    assert panel.spec.sample is None
    qtbot.waitUntil(lambda: panel.rehearsal is not None, timeout=60_000)
    assert "the sample's diameter is needed" in panel.rehearsal.failure()
    assert not panel.run_button.isEnabled()
