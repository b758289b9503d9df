"""Terminal face of a run: a rich progress bar with lab-time ETA and live values, as an
event subscriber, and the lines a scientist wants to see when states change.

Text is text: every string that reaches the console (step names, reasons, exception texts,
rig and protocol values echoed back, paths) is rendered as a :class:`rich.text.Text` or with
markup off, never parsed as rich markup, so ``[/x] hold`` or ``[limits] max_force`` shows as
written and cannot break the display."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, TaskID, TextColumn
from rich.text import Text

from gelrig.instrument.core.units import lab_time
from gelrig.protocols.events import (
    Event,
    Fault,
    FitUpdate,
    InterlockTrip,
    Note,
    SafeStopped,
    Samples,
    StateChanged,
    StepFinished,
    StepStarted,
)
from gelrig.protocols.events import (
    Progress as ProgressEvent,
)

#: Least time (s) between two redraws of the bars for progress events alone: at most about
#: 10 a second. Any other event the view shows (a step started or ended, a state line, a
#: fault) redraws at once; sample blocks redraw nothing (issue 31).
REFRESH_INTERVAL = 0.1


def fit_line(event: FitUpdate) -> str:
    """The live fit for the progress line: ``tau 1413 s +- 1.7 % (2 % at end), 1 term``."""
    st = event.state
    if not st.relax:
        return ""
    if st.terms_resolved < 1:
        return f"fit not resolved: {st.not_resolved or 'no term resolved yet'}"
    rel = st.tau_relative
    shown = f"{rel * 100:.2g} %" if math.isfinite(rel) else "undetermined"
    end = st.forecast.get("tau_1", math.nan)
    at_end = f" ({end * 100:.2g} % at end)" if math.isfinite(end) else ""
    terms = f"{st.terms_resolved} term{'s' if st.terms_resolved != 1 else ''} resolved"
    mark = "; target met" if event.met else ""
    return f"tau {st.tau:.4g} s +- {shown}{at_end}, {terms}{mark}"


def _values(values: dict[str, float]) -> str:
    out = []
    for key, value in values.items():
        if key.endswith("_m"):
            out.append(f"{key[:-2]} {value * 1e3:.4f} mm")
        elif key.endswith("_N"):
            out.append(f"{key[:-2]} {value * 1e3:.3f} mN")
        elif key.endswith("_m_s"):
            out.append(f"{key[:-4]} {value:.3g} m/s")
        else:
            out.append(f"{key} {value:.4g}")
    return ", ".join(out)


class ConsoleView:
    """Subscriber: one progress bar per step, state changes as lines, and one line per run
    that ends short: what happened, what the safe stop verified, where the details are.

    It renders only from the publishing thread (no auto-refresh thread): rich's lazy imports
    are not safe to race, and one thread is all a progress display needs; :meth:`say` prints
    from another thread under the same lock. It redraws on the events it shows, progress at
    most every :data:`REFRESH_INTERVAL` s of wall time (``clock``), never on sample blocks.
    """

    def __init__(self, console: Console | None = None, log_path: Path | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.console = console or Console(stderr=True)
        self._wall = clock
        self._drawn = -math.inf  # wall time of the last redraw
        self.redraws = 0
        self.log_path = log_path
        self._headline: Text | None = None  # the trip or fault waiting for its safe state
        self._closed = False
        self.progress = Progress(
            TextColumn("{task.description}", style="bold", markup=False), BarColumn(),
            TextColumn("{task.percentage:>5.1f}%"),
            TextColumn("ETA {task.fields[eta]}", markup=False),
            TextColumn("{task.fields[live]}", markup=False), console=self.console,
            transient=False, auto_refresh=False,
        )
        self._task: TaskID | None = None
        self._fit = ""  # the live fit's line during a hold
        self._lock = threading.RLock()  # say() may be re-entered by a signal handler

    def __enter__(self) -> ConsoleView:
        self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the progress display and show no more events (idempotent)."""
        self._closed = True
        if self._lock.acquire(timeout=1.0):
            try:
                if self.progress.tasks:
                    self.progress.stop()
                else:  # no step started: no empty line (Progress.stop prints one to a file)
                    self.progress.live.stop()
            finally:
                self._lock.release()

    def say(self, text: str) -> None:
        """Print a line from any thread (as written: no markup, no emoji codes)."""
        if self._lock.acquire(timeout=1.0):
            try:
                self.console.print(Text(text), soft_wrap=True)
            finally:
                self._lock.release()

    def __call__(self, event: Event) -> None:
        if self._closed:
            return
        if isinstance(event, Samples):
            return  # nothing shown changes with a sample block
        with self._lock:
            self._handle(event)
            now = self._wall()
            if isinstance(event, ProgressEvent | FitUpdate) and \
                    now - self._drawn < REFRESH_INTERVAL:
                return  # shown at the next redraw (a later progress, the step's end)
            self._drawn = now
            self.redraws += 1
            self.progress.refresh()

    def _handle(self, event: Event) -> None:
        if isinstance(event, StepStarted):
            self._task = self.progress.add_task(f"{event.index}: {event.name}", total=1.0,
                                                eta="?", live="")
        elif isinstance(event, ProgressEvent) and self._task is not None:
            live = event.message
            if event.values:
                live = f"{live} ({_values(dict(event.values))})" if live else _values(
                    dict(event.values))
            if self._fit and event.message == "hold":
                live = f"{live}; {self._fit}"
            self.progress.update(self._task, completed=event.fraction,
                                 eta=lab_time(event.remaining), live=live)
        elif isinstance(event, FitUpdate):
            self._fit = fit_line(event)
        elif isinstance(event, StepFinished):
            self._fit = ""
            end = event.results.get("hold_end") if isinstance(event.results, dict) else None
            if end in ("target", "maximum"):
                what = "target met" if end == "target" else "target not met: the maximum"
                self.console.print(Text(f"[{lab_time(event.t)}] step {event.index}: adaptive "
                                        f"hold ended after {event.results.get('held_s', 0):.0f}"
                                        f" s ({what})"))
            if self._task is not None:
                done = event.status == "completed"
                self.progress.update(self._task, completed=1.0 if done else None, eta="-",
                                     live=event.status)
            self._task = None
        elif isinstance(event, Note):  # printed above the live bars, which stay intact
            self.console.print(note_line(event), soft_wrap=True)
        elif isinstance(event, StateChanged) and event.reason and not event.new.finished:
            self.console.print(Text(f"[{lab_time(event.t)}] {event.new.value}: {event.reason}"),
                               soft_wrap=True)
        elif isinstance(event, InterlockTrip):
            self._headline = Text.assemble(("INTERLOCK", "bold red"), f" {event.message}")
        elif isinstance(event, Fault):
            self._headline = fault_headline(event)
        elif isinstance(event, SafeStopped):
            self.console.print(self._end_line(event), soft_wrap=True)

    def _end_line(self, event: SafeStopped) -> Text:
        """The one line of a run that ended short: what happened (the trip or fault waiting,
        else the abort), what the safe stop verified, where the details are."""
        head = self._headline or Text.assemble(("ABORTED", "bold yellow"),
                                               f" {event.state.reason}")
        self._headline = None
        safe = event.state.line()
        where = f"; details: {self.log_path}" if self.log_path else ""
        return Text.assemble(head, "; ", (safe, "" if event.state.verified else "bold red"),
                             where)


def note_line(event: Note) -> Text:
    """A script's ``run.log`` line as people see it: ``[lab time] text``, as written."""
    return Text(f"[{lab_time(event.t)}] {event.text}")


def fault_headline(event: Fault) -> Text:
    """``FAULT kind: message``, the message as written (it may be a script's exception text
    with brackets in it, or a cap's ``[limits]`` table)."""
    return Text.assemble(("FAULT", "bold red"), f" {event.kind}: {event.message}")
