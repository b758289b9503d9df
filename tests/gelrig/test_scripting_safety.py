"""Through the scripting API (issue 25, item 4): a move toward the sample before a contact
search is refused unless confirmed, and then limited to the safe approach speed; a
``safe_stop()`` that leaves the sample loaded does not report safe, and says what is
loaded."""

from pathlib import Path

import pytest

import gelrig
from gelrig.protocols.manual_motion import APPROACH_SPEED
from tests.rigs import compression_rig_with


def rig_file(tmp_path: Path, retract: str) -> Path:
    return compression_rig_with(tmp_path, f'retract_on_fault = "{retract}"')


def test_a_move_before_a_contact_search_is_refused_then_limited_to_the_approach_speed(
        tmp_path: Path) -> None:
    with gelrig.open_rig(rig_file(tmp_path, "2 mm")) as rig:
        rig.home()
        before = rig.readings()["position_m"]
        with pytest.raises(gelrig.FirstTouchUnknown, match="overlap limit is not armed"):
            rig.move_plate(1e-3, to=9e-3)
        assert rig.readings()["position_m"] == pytest.approx(before, abs=1e-6)  # nothing
        speeds: list[float] = []
        stage = rig.rig.stage
        real = stage.set_velocity

        def set_velocity(speed: float, acceleration: float) -> None:
            speeds.append(speed)
            real(speed, acceleration)

        stage.set_velocity = set_velocity  # type: ignore[method-assign]
        rig.move_plate(1e-3, to=5e-3, confirm=True)  # short of the sphere (6.2 mm)
        assert speeds == [APPROACH_SPEED]
        rig.move_plate(1e-3, to=1e-3)  # away from the sample: as asked
        assert speeds[-1] == 1e-3


def test_a_safe_stop_that_leaves_the_sample_loaded_does_not_report_safe(
        tmp_path: Path) -> None:
    with gelrig.open_rig(rig_file(tmp_path, "0 mm")) as rig:  # a safe stop only stops
        rig.home()
        rig.move_plate(1e-3, to=9e-3, confirm=True)  # 2.8 mm into the sphere
        assert rig.readings()["force_N"] > 0.1
        safe = rig.safe_stop()
        assert not safe.verified
        assert safe.line().startswith("motion stopped (verified); SAMPLE STILL LOADED: ")
        assert "mN on the sample" in safe.line()
        assert safe.as_dict()["verified"] is False
        rig.rig.unload()
    with gelrig.open_rig(rig_file(tmp_path, "2 mm")) as rig:  # first touch unknown: by force
        rig.home()
        rig.move_plate(1e-3, to=9e-3, confirm=True)
        safe = rig.safe_stop()
        assert safe.verified, safe.line()
        assert "mN read back" in safe.line() and "STILL LOADED" not in safe.line()
