"""A campaign member whose link freezes mid-run and then recovers gets its safe stop completed
like a run in the terminal (issue 32): the pending stop is tried again once the instrument
answers, run.json records ``safe_state.completed_later`` and the member's record says what was
verified. Members run on in-process twins (no served transport to cut): the link is the
KDC101 simulator's, frozen by muting it (it still obeys commands, it sends nothing) and thawed
3 s of wall time later; the simulator is read directly afterwards."""

from __future__ import annotations

import dataclasses
import json
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gelrig.campaign.member import run_member
from gelrig.campaign.spec import load_campaign
from tests.gelrig.campaign import tiny

#: Lab time (s) of the first request after which the stage's link freezes (in the hold).
FREEZE_AT = 40.0
#: Wall seconds the link stays frozen.
FROZEN_FOR = 3.0


@pytest.mark.slow
def test_a_frozen_link_that_recovers_gets_the_members_safe_stop_completed(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from gelrig.simulators import kdc101 as kdc101_sim

    sims: list[Any] = []
    real_register = kdc101_sim.register

    def register(sim: Any, name: str) -> str:
        sims.append(sim)
        receive = sim.receive

        def freezing_receive(data: bytes) -> None:
            if not sims[1:] and sim.clock.now() >= FREEZE_AT:
                sims.append("frozen")  # once: mute now, thaw later
                sim.mute()
                threading.Timer(FROZEN_FOR, sim.mute, args=(False,)).start()
            receive(data)

        sim.receive = freezing_receive
        return real_register(sim, name)

    monkeypatch.setattr(kdc101_sim, "register", register)
    member = load_campaign(tiny.write(tmp_path, tiny.COMPRESSION, replicates=1)).members[0]
    member = dataclasses.replace(member, keep_dir=str(tmp_path / "run"))
    row = run_member(member)

    assert sims[1:] == ["frozen"]
    assert row["status"] == "failed" and row["error"].startswith("run failed: Instrument")
    safe = json.loads((tmp_path / "run" / "run.json").read_text())["safe_state"]
    assert safe["verified"] is False  # at the fault: the link was frozen
    assert safe["line"].startswith("STOP SENT, NOT CONFIRMED")
    later = safe["completed_later"]
    assert later["verified"] is True and later["attempts"] >= 1
    assert later["line"].startswith("motion stopped (verified); plate retracted to ")
    # the member's record says so
    assert row["safe_stop"] == "completed later"
    assert row["safe_stop_line"].startswith(f"{later['line']} (after ")
    # the simulator itself: at rest where the retry says it retracted the plate
    sim = sims[0]
    now = np.array([sim.clock.now()])
    assert sim.velocity_at(now[0]) == 0
    plate = float(sim.positions_at(now)[0]) - sim.config.home_offset_m
    assert plate == pytest.approx(later["instruments"]["stage"]["position"], abs=2e-6)


def test_a_completed_members_record_needs_no_safe_stop() -> None:
    from gelrig.campaign.member import safe_stop_columns

    assert safe_stop_columns({"status": "completed"}) == {"safe_stop": "",
                                                          "safe_stop_line": ""}
    assert safe_stop_columns({"safe_state": {"line": "motion stopped (verified)",
                                             "verified": True}}) == {
        "safe_stop": "verified", "safe_stop_line": "motion stopped (verified)"}
    assert safe_stop_columns({"safe_state": {"line": "STOP SENT, NOT CONFIRMED: x",
                                             "verified": False}})["safe_stop"] == \
        "not confirmed"


def test_the_campaign_summary_says_what_each_safe_stop_verified() -> None:
    from gelrig.campaign.report import summary_lines

    rows = [{"member_id": "a", "seed": 1, "status": "failed", "error": "run failed: x",
             "safe_stop": "completed later", "safe_stop_line": "motion stopped (verified)"},
            {"member_id": "b", "seed": 2, "status": "failed", "error": "run failed: y",
             "safe_stop": "not confirmed", "safe_stop_line": "STOP SENT, NOT CONFIRMED: z"}]
    lines = summary_lines(rows)
    assert "    safe stop completed later: motion stopped (verified)" in lines
    assert lines[-1] == ("  1 member(s) whose safe stop was not confirmed, e.g. b: "
                         "STOP SENT, NOT CONFIRMED: z")
