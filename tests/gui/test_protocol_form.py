"""The protocol form reads values and ranges in the units the protocol file uses."""

from gelrig.gui.protocol_form import ProtocolForm

TABLE = {"protocol": {"name": "search", "rig": "compression"}, "step": [
    {"kind": "compression_contact_search", "start": "5 mm", "speed": "0.3 mm/s"}]}


def test_the_unit_beside_an_entry_is_the_one_typed_and_the_range_is_in_it(qtbot):
    form = ProtocolForm()
    qtbot.addWidget(form)
    form.set_table(TABLE, "<test>")
    speed = form.entry(0, "speed")
    assert speed.unit.text() == "mm/s"
    assert "mm/s" in speed.edit.toolTip()
    speed.edit.setText("9 mm/s")  # beyond the stage's top speed
    assert speed.error.text() and not speed.error.isHidden()
    assert speed.error.text().endswith("mm/s") and " m/s" not in speed.error.text()
    speed.edit.setText("0.0003")  # a bare number is SI: the label says so
    assert speed.unit.text() == "m/s"
    assert not speed.error.text() and speed.error.isHidden()
    assert form.spec is not None


def test_an_empty_entry_shows_the_unit_its_default_is_written_in(qtbot):
    form = ProtocolForm()
    qtbot.addWidget(form)
    form.set_table(TABLE, "<test>")
    probe = form.entry(0, "probe")  # not in the table: the default applies
    assert probe.edit.text() == ""
    shown = probe.edit.placeholderText().split()[-1]  # 'default 0.5 mm'
    assert shown != probe.field.unit  # a lab unit, not SI
    assert probe.unit.text() == shown
    assert shown in probe.edit.toolTip()  # and its range in it
    probe.edit.setText("0.0004")  # a bare number: SI, the label follows
    assert probe.unit.text() == probe.field.unit
    probe.edit.setText("")
    assert probe.unit.text() == shown
