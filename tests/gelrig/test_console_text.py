"""Text is text: whatever a user wrote (step names, exception texts, reasons, the rig file's
table names echoed back) reaches the terminal as written, never parsed as rich markup."""

from __future__ import annotations

import io

from hypothesis import given, settings
from hypothesis import strategies as st
from rich.console import Console

from gelrig.console import ConsoleView
from gelrig.protocols.events import (
    Fault,
    InterlockTrip,
    Progress,
    RunState,
    SafeStopped,
    StateChanged,
    StepFinished,
    StepStarted,
)
from gelrig.protocols.safestop import AxisState, SafeState

#: What breaks rich markup or emoji codes: closing tags, style names, table names, escapes.
HOSTILE = ["[/x] hold", "[bold]loud", "[limits] max_force", "a\\[b]", "end\\", ":warning:",
           "[link=file:///etc/passwd]x[/link]", "[/]", "[@click=quit]q", "[#ff0000]red"]

#: Text made of what markup is made of, and anything printable besides.
markupish = st.text(alphabet=st.sampled_from("[]/\\:@#=ab x"), min_size=1, max_size=30)
printable = st.text(alphabet=st.characters(blacklist_categories=("Cc", "Cs", "Zl", "Zp")),
                    min_size=1, max_size=30).filter(lambda s: s.strip() == s)
texts = st.one_of(st.sampled_from(HOSTILE), markupish, printable)


def view() -> tuple[ConsoleView, io.StringIO]:
    out = io.StringIO()
    return ConsoleView(Console(file=out, width=2000, force_terminal=False,
                               color_system=None)), out


def verified(reason: str) -> SafeState:
    axis = AxisState("stage", "plate", stop_sent=True, stopped=True, position=4.2e-3,
                     safe_action="plate retracted to 4.200 mm", safe_ok=True)
    return SafeState(reason, [axis])


def run_through(name: str, message: str) -> str:
    """A step named ``name`` runs, a state change and a fault carry ``message``, the run ends
    short; returns what the terminal got."""
    console, out = view()
    with console:
        console(StepStarted(0.0, 0, name, "ramp_hold", {}, {}))
        console(Progress(1.0, 0, 0.5, 1.0, 2.0, message, {"force_N": 0.01}))
        console(StateChanged(1.0, RunState.RUNNING, RunState.PAUSED, message))
        console(Fault(2.0, "RuntimeError", message))
        console(SafeStopped(2.0, verified(message)))
        console(StepFinished(2.0, 0, name, "failed", {"reason": message}))
        console.say(message)
    return out.getvalue()


@settings(max_examples=150, deadline=None)
@given(name=texts, message=texts)
def test_names_and_messages_are_shown_as_written(name: str, message: str) -> None:
    text = run_through(name, message)
    assert f"0: {name}" in text
    assert f"paused: {message}" in text
    assert f"FAULT RuntimeError: {message}; motion stopped (verified)" in text
    assert f"\n{message}\n" in text  # say()


def test_the_end_lines_keep_the_rig_files_table_names() -> None:
    console, out = view()
    with console:
        console(InterlockTrip(3.0, "force", 2.01, 2.0, "N",
                              "interlock force: 2.01 N beyond [limits] max_force 2 N"))
        console(SafeStopped(3.0, verified("trip")))
        console(SafeStopped(4.0, verified("aborted by [/x] Ctrl-C")))
    lines = out.getvalue().splitlines()
    assert lines[0] == ("INTERLOCK interlock force: 2.01 N beyond [limits] max_force 2 N; "
                        "motion stopped (verified); plate retracted to 4.200 mm")
    assert lines[1].startswith("ABORTED aborted by [/x] Ctrl-C; motion stopped (verified)")


def test_an_unverified_stop_and_a_log_path_with_brackets() -> None:
    out = io.StringIO()
    console = ConsoleView(Console(file=out, width=2000, force_terminal=False),
                          log_path="runs/[/x]/gelrig.log")  # type: ignore[arg-type]
    unreachable = SafeState("x", [AxisState("stage", "plate", stop_sent=True,
                                            errors=["[/y] gone"])])
    with console:
        console(Fault(1.0, "Disconnected", "KDC101: [/x] link lost"))
        console(SafeStopped(1.0, unreachable))
    assert out.getvalue().strip() == (
        "FAULT Disconnected: KDC101: [/x] link lost; STOP SENT, NOT CONFIRMED: stage "
        "unreachable - check the rig; details: runs/[/x]/gelrig.log")


def test_the_bars_redraw_on_what_they_show_at_most_ten_times_a_second():
    """Sample blocks redraw nothing; progress at most every 0.1 s of wall time; a step's
    start or end and a state line at once; the last progress is shown all the same
    (issue 31: 8,953 redraws for 50 progress events)."""
    import numpy as np

    from gelrig.protocols.events import Samples

    now = [0.0]
    out = io.StringIO()
    console = ConsoleView(Console(file=out, width=200, force_terminal=False, color_system=None),
                          clock=lambda: now[0])
    block = Samples(0.0, 0, {"force_N": np.zeros(100)})
    with console:
        console(StepStarted(0.0, 0, "hold", "ramp_hold", {}, {}))
        assert console.redraws == 1
        for k in range(100):  # 1 s of wall time: 100 progress events, 1000 sample blocks
            now[0] = 0.01 * (k + 1)
            for _ in range(10):
                console(block)
            console(Progress(k, 0, (k + 1) / 100, k, 100 - k, "hold", {}))
        assert 9 <= console.redraws - 1 <= 11
        before = console.redraws
        console(StateChanged(1.0, RunState.RUNNING, RunState.PAUSED, "paused by you"))
        assert console.redraws == before + 1
        console(StepFinished(2.0, 0, "hold", "completed", {}))
    assert "100.0%" in out.getvalue()
