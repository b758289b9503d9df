"""The stop reaches the instrument, and gelrig says how (issue 32, items 1, 3 and 4).

Through the real transports: ``gelrig run`` against ``gelrig sim serve`` processes, the one
under test frozen with SIGSTOP, or its link cut by the fault proxy while it stays up and
accepts new clients. Afterwards the served simulator is read directly, by a client gelrig did
not write (pyvisa for the MCR 501, pylablib for the KDC101), not only through gelrig's word.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

from tests.frozen_runs import FrozenRun, frozen_run
from tests.served import Served

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs SIGSTOP")

#: README figures (s, freeze to the terminal's line, medians of
#: benchmarks/bench_frozen_stop.py); a test allows twice that on a loaded machine.
README_TO_LINE = {"kdc101": 2.5, "usb6001": 8.9, "mcr501": 3.6}


def _mcr501_state(served: Served) -> tuple[str, float]:
    """The served MCR 501's mode and gap (mm), asked over pyvisa."""
    import pyvisa

    rm = pyvisa.ResourceManager("@py")
    try:
        res = rm.open_resource(f"TCPIP0::127.0.0.1::{served.port}::SOCKET",
                               read_termination="\r\n", write_termination="\r\n",
                               timeout=2000)
        status = str(res.query(":STAT[?]"))
        gap = str(res.query(":GAP[?]"))
        res.close()
    finally:
        rm.close()
    return status, float(gap.split("[", 1)[1].rstrip("]"))


def _kdc101_state(served: Served) -> tuple[bool, int]:
    """Whether the served KDC101 moves, and its position (counts), asked by pylablib."""
    kinesis = pytest.importorskip("pylablib.devices.Thorlabs.kinesis", exc_type=ImportError)
    motor = kinesis.KinesisMotor(("serial", f"socket://127.0.0.1:{served.port}"),
                                 scale="step")
    try:
        return bool(motor.is_moving()), int(motor.get_position())
    finally:
        motor.close()


def _facts(run: FrozenRun, instrument: str) -> dict[str, Any]:
    safe = run.meta["safe_state"]
    facts: dict[str, Any] = safe["instruments"][instrument]
    assert safe["line"] in run.line, (run.line, safe)
    return facts


@pytest.mark.parametrize("instrument", ["kdc101", "usb6001", "mcr501"])
def test_a_frozen_instrument_ends_the_run_within_the_readme_figure(
        tmp_path: Path, instrument: str) -> None:
    """Safe stop first: no step cleanup spends reply timeouts before it (was 16 s, MCR 501)."""
    # the stage and the rheometer stay unconfirmed: a Ctrl-C gives up gelrig's retries
    run = frozen_run(instrument, tmp_path,
                     give_up_after=None if instrument == "usb6001" else 2.5)
    assert run.returncode == 1, run.output
    assert run.line.startswith("FAULT InstrumentTimeout"), run.output
    assert run.to_line < 2 * README_TO_LINE[instrument], (run.to_line, run.line)
    assert "Traceback" not in run.output
    moving = "rheometer" if instrument == "mcr501" else "stage"
    facts = _facts(run, moving)
    assert facts["stop_sent"] is True  # written on a link that was up
    if instrument == "usb6001":  # the stage answers: stopped, back to the end of travel
        assert run.meta["safe_state"]["verified"] is True
        assert "plate retracted to 0.000 mm (end of travel: the load could not be read)" \
            in run.line
    else:
        assert "STOP SENT, NOT CONFIRMED" in run.line
        # gelrig keeps trying while it lives; a Ctrl-C gives that up
        assert "trying again every 1 s for up to 60 s (Ctrl-C gives up)" in run.output
        assert "SAFE STOP NOT COMPLETED given up by Ctrl-C - check the rig" in run.output
        assert "completed_later" not in run.meta["safe_state"]


@pytest.mark.parametrize("instrument", ["kdc101", "mcr501"])
def test_a_dropped_link_is_reopened_and_the_stop_sent_on_the_new_one(
        tmp_path: Path, instrument: str) -> None:
    """The link drops mid-run, the instrument stays up: the stop goes out on a new link, is
    verified, the sample made safe; the simulator, read directly, is at rest there."""
    reader = _mcr501_state if instrument == "mcr501" else _kdc101_state
    run = frozen_run(instrument, tmp_path, fault="drop", inspect=reader)
    assert run.returncode == 1, run.output
    moving = "rheometer" if instrument == "mcr501" else "stage"
    facts = _facts(run, moving)
    assert run.meta["safe_state"]["verified"] is True, run.meta["safe_state"]
    assert facts["stop_sent"] is True and facts["reconnected"] is True
    assert any("NotSent" in e for e in facts["errors"]), facts  # the old link's write failed
    assert f"motion stopped (verified; {moving} stop sent on a new link)" in run.line
    if instrument == "mcr501":
        status, gap_mm = run.inspected
        assert "IDLE" in status, status
        assert gap_mm == pytest.approx(facts["position"] * 1e3, abs=1e-3)
    else:
        is_moving, counts = run.inspected
        assert not is_moving
        assert counts == pytest.approx(facts["position"] * 1e3 * 34554.96, abs=3)


def test_a_frozen_link_that_recovers_gets_its_safe_stop_completed(tmp_path: Path) -> None:
    """The stop is not confirmed while the MCR 501 is frozen; once it answers again the
    pending safe stop stops, reads back and lifts, and says so in run.json and one line."""
    run = frozen_run("mcr501", tmp_path, fault="recover", thaw_after=3.0,
                     inspect=_mcr501_state)
    assert "STOP SENT, NOT CONFIRMED" in run.line
    later = run.meta["safe_state"]["completed_later"]
    assert later["verified"] is True and later["attempts"] >= 1
    assert later["line"].startswith("motion stopped (verified); arm lifted to gap")
    completed = [t for t in run.output.splitlines() if t.startswith("SAFE STOP COMPLETED LATER")]
    assert completed == [f"SAFE STOP COMPLETED LATER: {later['line']}; details: "
                         f"{tmp_path / 'run' / 'gelrig.log'}"], run.output
    status, gap_mm = run.inspected
    assert "IDLE" in status
    assert gap_mm == pytest.approx(later["instruments"]["rheometer"]["position"] * 1e3,
                                   abs=1e-3)
    assert run.returncode == 1
