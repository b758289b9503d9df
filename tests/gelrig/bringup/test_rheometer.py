"""MCR 501 bring-up on the twin: the whole command table meets the simulator that serves it."""

from __future__ import annotations

import pytest

from gelrig.bringup import runner
from gelrig.bringup.rheometer import check_reply
from gelrig.drivers.mcr501.commands import COMMANDS
from gelrig.protocols.rigfile import default_rig


def test_every_command_is_sent_and_agrees_with_the_simulator(tmp_path):
    outcome = runner.run(default_rig("shear"), lambda r, c, s: runner.twin_operator(r, c, s),
                         tmp_path / "shear.confirmed.toml")
    table = next(line for line in outcome.findings if line.startswith("command table"))
    assert f"over {len(COMMANDS)} commands of {len(COMMANDS)}; 0 differ" in table
    noise = next(line for line in outcome.findings if line.startswith("torque zero"))
    # the built-in shear rig's truth: 1e-7 N*m and 2e-5 N (standard deviations)
    torque = float(noise.split("noise ")[1].split(" uN*m")[0])
    force = float(noise.split("noise ")[2].split(" mN")[0])
    assert torque == pytest.approx(0.1, rel=0.15) and force == pytest.approx(0.02, rel=0.15)
    assert outcome.written is None  # nothing of the shear rig is a rig-file value yet


@pytest.mark.parametrize(("name", "lines", "why"), [
    ("read_gap", [":GAP[3.0000;1]"], "expected :GAP[gap_mm]"),
    ("identify", ["#ERR[10;unknown command]"], "error reply"),
    ("read_stream", ["#DATA[1;0]", ":MEAS[0.1;2]"], "is not :MEAS"),
])
def test_a_reply_unlike_the_table_is_shown(name, lines, why):
    ok, note = check_reply(COMMANDS[name], lines)
    assert not ok and why in note


def test_a_reply_as_the_table_says_passes():
    assert check_reply(COMMANDS["read_gap"], [":GAP[3.0000]"]) == (True, "")
