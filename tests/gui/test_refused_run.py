"""A run refused before anything moved leaves no run folder (ADR 0330), in the window too: a
protocol file the built rig's caps refuse is said in one line and no folder is made; a
script's first step refused as it is sent ends the run "refused" and its folder goes."""

import math

import pytest

from gelrig.protocols.events import RunState
from gelrig.protocols.resolve import resolve_procedure
from tests.gelrig.test_cli_text import FAST, REFUSED, slow_rig
from tests.gelrig.test_scripting import REFUSED_SCRIPT
from tests.gui.test_truthful_state import shown_window


@pytest.fixture
def slow_window(qtbot, tmp_path):
    """A window on a simulated compression rig whose stage goes at most 1 mm/s."""
    with shown_window(qtbot, slow_rig(tmp_path), math.inf, tmp_path / "runs") as window:
        yield window


def said(qtbot, window):
    """The window's last message is the refusal: its one line, then what it means."""
    qtbot.waitUntil(lambda: window.last_message is not None
                    and window.last_message.windowTitle() == "Run refused", timeout=10_000)
    lines = window.last_message.text().splitlines()
    assert lines[0] == REFUSED and "no run folder" in lines[-1]


def run_folders(tmp_path):
    runs = tmp_path / "runs"
    return [p for p in runs.iterdir() if p.is_dir()] if runs.exists() else []


def test_a_protocol_the_rigs_caps_refuse_is_one_line_and_makes_no_folder(
        qtbot, slow_window, tmp_path):
    window = slow_window
    protocol = tmp_path / "fast.toml"
    protocol.write_text(FAST)
    window.protocol.load_file(protocol)
    qtbot.waitUntil(lambda: window.protocol.run_button.isEnabled(), timeout=30_000)
    window.protocol.run_button.click()
    said(qtbot, window)
    assert f"run refused: {REFUSED}; no run folder made" in window.log.toPlainText()
    assert not window.desk.running and window.desk.run_path is None
    assert run_folders(tmp_path) == []


def test_a_script_refused_at_its_first_step_leaves_no_folder(qtbot, slow_window, tmp_path):
    window = slow_window
    script = tmp_path / "s.py"
    script.write_text(REFUSED_SCRIPT)
    procedure = resolve_procedure(script, {"speed": "1.31 mm/s"})
    path = window.desk.start_run(procedure)
    assert path.is_dir()  # a script's steps are only known as it sends them
    qtbot.waitUntil(lambda: not window.desk.running, timeout=60_000)
    assert window.desk.state is RunState.REFUSED
    assert window.desk.refused == REFUSED
    assert not path.exists() and run_folders(tmp_path) == []
    assert window.desk.run_path is None
    said(qtbot, window)
    assert not window.report_button.isVisible()
