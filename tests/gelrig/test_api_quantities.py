"""Unit strings everywhere the scripting API takes a quantity (issue 27): ``move_plate`` and
``set_gap`` take ``"0.5 mm/s"``, ``"3 mm"`` or SI numbers, through the whole simulated rig; a
bad value is one line naming the argument, the value and what is allowed, and nothing
moves."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

import gelrig


def where(rig: gelrig.RigSession, key: str) -> float:
    return rig.readings()[key]


def test_move_plate_takes_unit_strings_and_si_numbers() -> None:
    with gelrig.open_rig("compression") as rig:
        rig.home()
        done = rig.move_plate("0.5 mm/s", to="3 mm", confirm=True)  # toward, before a search
        assert done.outcome == "done"
        assert where(rig, "position_m") == pytest.approx(3e-3, abs=1e-6)
        rig.move_plate("0.5 mm/s", by="-0.1 mm")
        assert where(rig, "position_m") == pytest.approx(2.9e-3, abs=1e-6)
        rig.move_plate(0.5e-3, to=2e-3)
        assert where(rig, "position_m") == pytest.approx(2e-3, abs=1e-6)
        rig.move_plate("500 um/s", by="-1000 um")
        assert where(rig, "position_m") == pytest.approx(1e-3, abs=1e-6)


@pytest.fixture(scope="module")
def rig_at_2_mm() -> Iterator[gelrig.RigSession]:
    """One simulated compression rig, homed and at 2 mm, for every refused move (opening and
    homing one per case cost 6-10 s each; a refused move leaves it where it was)."""
    with gelrig.open_rig("compression") as rig:
        rig.home()
        rig.move_plate("1 mm/s", to="2 mm", confirm=True)
        yield rig


@pytest.mark.parametrize(("speed", "kwargs", "line"), [
    ("fast", {"to": "3 mm"},
     """move_plate speed = "fast": a number in m/s, or a string with a unit like '0.5 mm/s'"""),
    ("2 mm", {"by": "-1 mm"},
     """move_plate speed = "2 mm": a number in m/s, or a string with a unit like '0.5 mm/s'"""),
    ("0.5 mm/s", {"to": "3 mm/s"},
     """move_plate to = "3 mm/s": a number in m, or a string with a unit like '3 mm'"""),
    ("0.5 mm/s", {"by": [1]},
     """move_plate by = [1]: a number in m, or a string with a unit like '3 mm'"""),
])
def test_a_bad_quantity_is_one_line_and_nothing_moves(
        rig_at_2_mm: gelrig.RigSession, speed: Any, kwargs: dict[str, Any], line: str) -> None:
    rig = rig_at_2_mm
    assert where(rig, "position_m") == pytest.approx(2e-3, abs=1e-6)
    with pytest.raises(gelrig.ConfigError) as raised:
        rig.move_plate(speed, **kwargs)
    assert str(raised.value) == line
    assert where(rig, "position_m") == pytest.approx(2e-3, abs=1e-6)


def test_set_gap_takes_a_unit_string() -> None:
    with gelrig.open_rig("shear") as rig:
        rig.rig.zero_gap()  # the lift's reference, as a shear step makes it
        rig.set_gap("4 mm")  # above the simulated touch gap (3 mm): nothing touches
        assert where(rig, "gap_m") == pytest.approx(4e-3, abs=2e-6)
        rig.set_gap(4.5e-3)
        assert where(rig, "gap_m") == pytest.approx(4.5e-3, abs=2e-6)
        with pytest.raises(gelrig.ConfigError, match=r'^set_gap gap = "4 N": a number in m'):
            rig.set_gap("4 N")
        assert where(rig, "gap_m") == pytest.approx(4.5e-3, abs=2e-6)
