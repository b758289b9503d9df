"""The console operator: what a person types, read as SI values; asked again when wrong."""

from __future__ import annotations

import pytest

from gelrig.bringup.operator import AWAY, TOWARD, ConsoleOperator


def _operator(*answers: str) -> tuple[ConsoleOperator, list[str]]:
    queue, shown = list(answers), []
    return ConsoleOperator("ana", read=lambda prompt: (shown.append(prompt), queue.pop(0))[1],
                           write=shown.append), shown


def test_yes_and_no_and_a_repeat_on_anything_else():
    op, shown = _operator("maybe", "y", "no")
    assert op.confirm("k", "Go?") is True
    assert op.confirm("k", "Go?") is False
    assert "  answer y or n" in shown


@pytest.mark.parametrize(("typed", "metres"), [("0.512", 0.512e-3), ("512 um", 512e-6),
                                               ("0.0512 cm", 0.512e-3)])
def test_a_gauge_reading_is_mm_unless_a_unit_is_given(typed, metres):
    op, _ = _operator(typed)
    assert op.gauge_reading() == pytest.approx(metres)


def test_a_bad_gauge_reading_is_asked_again_with_a_one_line_reason():
    op, shown = _operator("12 N", "0.5")
    assert op.gauge_reading() == pytest.approx(0.5e-3)
    assert any("expected a quantity in m" in line for line in shown)


def test_a_mass_is_grams_and_the_way_the_plate_went_is_a_word():
    op, _ = _operator("100.02", "0.2 kg", "sideways", "t", "away")
    assert op.load_mass(0.1) == pytest.approx(0.10002)
    assert op.load_mass(0.2) == pytest.approx(0.2)
    assert op.plate_went() == TOWARD
    assert op.plate_went() == AWAY


def test_the_gain_defaults_to_the_rig_files_and_refuses_nonsense():
    op, shown = _operator("", "500", "-3")
    assert op.conditioner_gain(1000.0) == 1000.0
    assert op.conditioner_gain(1000.0) == 500.0
    assert op.conditioner_gain(1000.0) == 1000.0
    assert any("kept 1000" in line for line in shown)
