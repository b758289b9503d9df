"""A run in the terminal: the console view, Ctrl-C, and the end of a stuck run.

The terminal's front end over :class:`~gelrig.protocols.host.RunHost`, used by ``gelrig run``,
``gelrig resume``, ``gelrig demo`` and the scripting API. Ctrl-C pauses at the next checkpoint
(Enter resumes); a second Ctrl-C aborts, which stops all motion at once; if the run is stuck in
an instrument call, the process ends within seconds all the same: the host's safe stop from
outside the run, its one line, and ``exit`` (3 aborted, 1 failed). The log, tracebacks
included, goes to RUN_DIR/gelrig.log; the terminal gets one line per fault.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from types import FrameType
from typing import Any

# imported with this module, before any run shows as "running": a Ctrl-C pressed once a run
# shows as running finds its handler installed at once (not after rich's imports)
from gelrig.console import ConsoleView
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import RunState
from gelrig.protocols.host import RunHost
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rigfile import RigSpec

log = logging.getLogger(__name__)


class Interrupts:
    """Ctrl-C presses of a run: the first pauses (Enter resumes), the second aborts, a
    third ends a stuck run at once. With ``pause_first`` False (the scripting API: there
    may be nobody to press Enter) the first aborts and the second ends a stuck run."""

    def __init__(self, control: RunControl, say: Callable[[str], object],
                 pause_first: bool = True):
        self.control = control
        self.say = say
        self.presses = 0
        self.pause_first = pause_first
        #: the console view the presses are told in (None: not shown)
        self.view: ConsoleView | None = None

    @property
    def urged(self) -> bool:
        """Ctrl-C was pressed once more after the abort: end a stuck run at once."""
        return self.presses >= (3 if self.pause_first else 2)

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.presses += 1
        if not self.pause_first and self.presses == 1:
            self.control.abort("aborted by Ctrl-C")
            self.say("aborting: stopping all motion")
        elif not self.pause_first:
            self.say("ending now")
        elif self.presses == 1:
            self.control.pause()
            where = ("the hold runs on (pausing would change the physics) and the run pauses "
                     "at the checkpoint after it" if self.control.holding
                     else "the run pauses at the next checkpoint")
            self.say(f"pause requested: {where}; press Enter to resume, Ctrl-C again to "
                     "abort")
            if sys.stdin is not None and sys.stdin.isatty():
                threading.Thread(target=_resume_on_enter, args=(self.control,),
                                 daemon=True).start()
        elif self.presses == 2:
            self.control.abort("aborted by Ctrl-C")
            self.say("aborting: stopping all motion")
        else:
            self.say("ending now")


@contextlib.contextmanager
def interrupt_handling(control: RunControl, say: Any, pause_first: bool = True
                       ) -> Iterator[Interrupts]:
    """First Ctrl-C pauses (Enter resumes), the second aborts (``pause_first`` False: the
    first aborts); restored afterwards."""
    interrupts = Interrupts(control, say, pause_first)
    if threading.current_thread() is not threading.main_thread():
        yield interrupts
        return
    previous = signal.signal(signal.SIGINT, interrupts)
    try:
        yield interrupts
    finally:
        signal.signal(signal.SIGINT, previous)


def _resume_on_enter(control: RunControl) -> None:
    with contextlib.suppress(Exception):
        sys.stdin.readline()
        if not control.abort_requested:
            control.resume()


def run_in_terminal(host: RunHost, show: bool = True,
                    exit: Callable[[int], object] = os._exit,
                    ctrl_c: str = "pause") -> RunState:
    """Run ``host`` (entered) on its worker thread with the console view and Ctrl-C; returns
    the final state. A run stuck after an abort is ended from outside by the host, which
    records it in run.json; this prints its one line and calls ``exit`` (3 aborted, 1
    failed): the process must not wait on a thread frozen in an instrument call.

    ``ctrl_c``: "pause" (the CLI: the first Ctrl-C pauses, the second aborts) or "raise"
    (the scripting API: the first aborts, and once the run has ended, with motion stopped
    and the end recorded, KeyboardInterrupt is raised here)."""
    with terminal_face(host, show, ctrl_c) as interrupts:
        host.start()
        watch(host, host.wait, interrupts, exit)
    complete_pending(host, show)
    state = host.outcome()
    if ctrl_c == "raise" and interrupts.presses:
        raise KeyboardInterrupt
    return state


@contextlib.contextmanager
def terminal_face(host: RunHost, show: bool, ctrl_c: str = "pause") -> Iterator[Interrupts]:
    """While it lasts: the console view of ``host``'s events (``show``) and Ctrl-C mapped
    onto its control (``ctrl_c`` as for :func:`run_in_terminal`); yields the presses."""
    if ctrl_c not in ("pause", "raise"):
        raise ValueError(f"ctrl_c = {ctrl_c!r}: allowed pause, raise")
    view = ConsoleView(log_path=host.log_path) if show else None
    say: Callable[[str], object] = view.say if view else (lambda *_: None)
    with contextlib.ExitStack() as stack:
        if view is not None:
            stack.enter_context(view)
            stack.callback(host.bus.subscribe(view))
        interrupts = stack.enter_context(interrupt_handling(host.control, say,
                                                            pause_first=ctrl_c == "pause"))
        interrupts.view = view
        yield interrupts


def watch(host: RunHost, done: Callable[[float], bool], interrupts: Interrupts,
          exit: Callable[[int], object] = os._exit) -> None:
    """Wait until ``done(timeout)`` says so or the run has ended; a run stuck after an abort
    is ended from outside (its one line printed, then ``exit``)."""
    while not done(0.1) and not host.ended:
        if host.stuck(urged=interrupts.urged):
            if interrupts.view is not None:
                interrupts.view.close()  # from now on this thread tells the end, in one line
            host.end_from_outside()
            print(host.outside_line(), file=sys.stderr, flush=True)
            exit(1 if host.outside_status == "failed" else 3)
            host.wait(1.0)  # ``exit`` returned (a test, the API): let the thread be
            break


def complete_pending(host: RunHost, show: bool = True) -> None:
    """A safe stop not confirmed is tried again while the process lives (see
    :meth:`RunHost.complete_pending`); one line says when it starts and one how it ended."""
    from gelrig.protocols.host import PENDING_LIMIT, PENDING_PERIOD

    if host.pending is None:
        return
    if show:
        print(f"gelrig: the safe stop is not confirmed; trying again every {PENDING_PERIOD:g} s "
              f"for up to {PENDING_LIMIT:g} s (Ctrl-C gives up)", file=sys.stderr, flush=True)
    safe = host.complete_pending()
    if not show:
        return
    if safe is not None:
        print(f"SAFE STOP COMPLETED LATER: {safe.line()}; details: {host.log_path}",
              file=sys.stderr, flush=True)
    else:
        why = "given up by Ctrl-C" if host.pending_given_up else f"within {PENDING_LIMIT:g} s"
        print(f"SAFE STOP NOT COMPLETED {why} - check the rig; details: {host.log_path}",
              file=sys.stderr, flush=True)


def record_run(procedure: Procedure, rig_spec: RigSpec, clock: Clock, run: RunDirectory,
               completed: Mapping[int, Mapping[str, Any]] | None = None, show: bool = True,
               exit: Callable[[int], object] = os._exit) -> tuple[RunState, RunHost]:
    """Build the rig of ``rig_spec`` on ``clock``, run ``procedure`` into ``run`` in the
    terminal (:func:`run_in_terminal`), close the rig; returns the final state and the host
    (its runner holds every step's results). For scripts of the benchmarks and tests."""
    from gelrig.factory import build_rig
    from gelrig.protocols.host import closing_rig

    with closing_rig(build_rig(rig_spec, clock)) as rig, \
            RunHost(rig, procedure, run, completed=completed) as host:
        state = run_in_terminal(host, show, exit)
    return state, host
