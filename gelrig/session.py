"""One run from the command line: build the rig, record, show progress, handle Ctrl-C.

Used by ``gelrig run``, ``gelrig resume`` and ``gelrig demo``. Ctrl-C pauses at the next
checkpoint (Enter resumes); a second Ctrl-C aborts, which stops all motion at once. The data
of every step streams to the run directory while it is acquired.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import FrameType
from typing import Any

from gelrig import __version__
from gelrig.factory import build_rig
from instrument.clock import Clock, RealClock
from instrument.errors import ConfigError
from instrument.store import RunDirectory
from protocols.control import RunControl
from protocols.events import EventBus, RunState
from protocols.rigfile import RigSpec
from protocols.runner import Runner
from protocols.session import RecordedRun
from protocols.spec import ProtocolSpec


def check_clock(rig: RigSpec, clock: Clock, spec: str) -> None:
    """A virtual or paced clock only makes sense when every instrument is simulated."""
    if not isinstance(clock, RealClock) and not rig.simulated:
        raise ConfigError("--clock", spec, f"rig {rig.source} has real instruments; "
                          "use --clock real (virtual and paced time need a simulated rig)")


@contextlib.contextmanager
def interrupt_handling(control: RunControl, say: Any) -> Iterator[None]:
    """First Ctrl-C pauses (Enter resumes), the second aborts; restored afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    presses = 0

    def handler(signum: int, frame: FrameType | None) -> None:
        nonlocal presses
        presses += 1
        if presses == 1:
            control.pause()
            say("pause requested: the run pauses at the next checkpoint; press Enter to "
                "resume, Ctrl-C again to abort")
            if sys.stdin is not None and sys.stdin.isatty():
                threading.Thread(target=_resume_on_enter, args=(control,), daemon=True).start()
        else:
            control.abort("aborted by Ctrl-C")
            say("aborting: stopping all motion")

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _resume_on_enter(control: RunControl) -> None:
    with contextlib.suppress(Exception):
        sys.stdin.readline()
        if not control.abort_requested:
            control.resume()


def metadata(protocol: ProtocolSpec, rig: RigSpec, clock_spec: str) -> dict[str, Any]:
    return {
        "software": {"name": "gelrig", "version": __version__, "python": sys.version.split()[0]},
        "protocol": protocol.table, "protocol_file": protocol.source,
        "rig": rig.table, "rig_file": rig.source, "clock": clock_spec,
        "started_wall": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def execute(
    protocol: ProtocolSpec,
    rig_spec: RigSpec,
    clock: Clock,
    run: RunDirectory,
    completed: Mapping[int, Mapping[str, Any]] | None = None,
    show: bool = True,
    bus: EventBus | None = None,
    control: RunControl | None = None,
) -> tuple[RunState, Runner]:
    """Build the rig, run the protocol into ``run``, close the rig; returns the final state."""
    from gelrig.console import ConsoleView

    rig = build_rig(rig_spec, clock)
    try:
        recorded = RecordedRun(rig, protocol, bus, control, completed).record(run)
        view = ConsoleView() if show else None
        with contextlib.ExitStack() as stack:
            if view is not None:
                stack.enter_context(view)
                recorded.bus.subscribe(view)
            stack.enter_context(interrupt_handling(
                recorded.control, view.console.print if view else lambda *_: None))
            state = recorded.run()
    finally:
        rig.close()
    return state, recorded.runner


def default_run_dir(protocol: ProtocolSpec) -> Path:
    slug = "".join(c if c.isalnum() else "-" for c in protocol.rig)
    return Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{slug}"
