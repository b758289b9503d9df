"""A run stuck in a frozen instrument ends with the same run.json whichever front end ran it.

The same fault on the same rig of fakes: the load cell freezes in the hold (its read ignores
every deadline) and the watchdog fires; the run thread cannot see that. ``gelrig run``'s
terminal and the GUI both hand the run to the run host, whose end from outside (the safe
stop, bounded, from another thread) writes run.json; the records must agree.
"""

import copy
import dataclasses
import json
import math
import re
from pathlib import Path

from gelrig.commands.gui import make_services
from gelrig.gui.mainwindow import MainWindow
from gelrig.protocols import host as hosting
from gelrig.protocols.events import RunState
from gelrig.protocols.host import RunHost, create_run
from gelrig.protocols.resolve import resolve_rig
from gelrig.protocols.rig import CompressionLimits
from gelrig.protocols.rigfile import default_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import run_in_terminal
from tests.doubles import compression_rig
from tests.gui.test_app import short_compression

#: Lab time (s) at which the load cell freezes: in the hold (the ramp ends near 20 s).
FREEZE_AT = 60.0
WATCHDOG = 0.3


def stuck_rig():
    rig, stage, force = compression_rig(limits=CompressionLimits(watchdog=WATCHDOG))
    force.faults.freeze_at = FREEZE_AT
    return rig, stage, force


def the_end(run_dir: Path) -> dict:
    """What run.json says of the end, with the wall-time figures (the watchdog's silent
    seconds, the safe stop's duration) left out."""
    meta = json.loads((run_dir / "run.json").read_text())

    def masked(text: str) -> str:
        return re.sub(r"no data for \d+ s", "no data for N s", text)

    safe = dict(meta["safe_state"])
    safe["reason"] = masked(safe["reason"])
    safe.pop("wall_s")  # how long the safe stop took in wall time
    return {
        "status": meta["status"],
        "reason": masked(meta["reason"]),
        "faults": [(f["kind"], masked(f["message"])) for f in meta.get("faults", [])],
        "safe_state": safe,
        "steps": [(s["name"], s["kind"], s["status"]) for s in meta["steps"]],
    }


def terminal_run(tmp_path: Path) -> tuple[dict, list[int]]:
    """As ``gelrig run``: the run directory, the host, the terminal face (exit recorded)."""
    rig, _stage, force = stuck_rig()
    protocol = parse_protocol(copy.deepcopy(short_compression(hold="3000 s")), "<test>")
    spec = resolve_rig(default_rig("compression"), protocol)
    run = create_run(protocol, spec, "virtual", tmp_path / "cli")
    codes: list[int] = []
    try:
        with RunHost(rig, protocol, run) as host:
            state = run_in_terminal(host, show=False, exit=codes.append)
    finally:
        force.faults.thaw()
    assert state is RunState.FAILED
    return the_end(run.path), codes


def gui_run(qtbot, tmp_path: Path) -> dict:
    """As at the rig: the window on the same fakes, Run pressed, nobody touches STOP."""
    base = make_services(default_rig("compression"), math.inf, tmp_path / "runs")
    rig, _stage, force = stuck_rig()
    window = MainWindow(dataclasses.replace(base, build_rig=lambda spec, clock: rig))
    window.show()
    window.start()
    try:
        qtbot.waitUntil(lambda: window.desk.rig is not None, timeout=10_000)
        window.protocol.set_table(short_compression(hold="3000 s"), "<test>")
        window.protocol.run_button.click()
        qtbot.waitUntil(lambda: window.desk.running, timeout=10_000)
        qtbot.waitUntil(lambda: not window.desk.running, timeout=40_000)
        assert force.faults.blocked.is_set()  # the run thread is still stuck in the read
        assert window.protocol.state == RunState.FAILED
        path = window.desk.run_path
        assert path is not None
        return the_end(path)
    finally:
        force.faults.thaw()
        window.close()
        if window.isVisible():
            window.desk.shutdown(5.0)


def test_cli_and_gui_record_the_same_end_of_a_stuck_run(qtbot, tmp_path, monkeypatch):
    monkeypatch.setattr(hosting, "GRACE", 0.3)
    cli, codes = terminal_run(tmp_path)
    gui = gui_run(qtbot, tmp_path)
    assert codes == [1]  # failed: the watchdog's fault, not a person's abort
    assert cli["status"] == "failed" and "stuck in an instrument call" in cli["reason"]
    assert cli["faults"][-1][0] == "WatchdogExpired"
    assert cli["safe_state"]["verified"] is True
    assert gui == cli
