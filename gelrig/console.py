"""Terminal face of a run: a rich progress bar with lab-time ETA and live values, as an
event subscriber, and the lines a scientist wants to see when states change."""

from __future__ import annotations

import math
import threading
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, TaskID, TextColumn

from instrument.units import lab_time
from protocols.events import (
    Event,
    Fault,
    FitUpdate,
    InterlockTrip,
    SafeStopped,
    StateChanged,
    StepFinished,
    StepStarted,
)
from protocols.events import (
    Progress as ProgressEvent,
)


def fit_line(event: FitUpdate) -> str:
    """The live fit for the progress line: ``tau 1413 s +- 1.7 % (2 % at end), 1 term``."""
    st = event.state
    if not st.relax:
        return ""
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
    from another thread under the same lock.
    """

    def __init__(self, console: Console | None = None, log_path: Path | None = None):
        self.console = console or Console(stderr=True)
        self.log_path = log_path
        self._headline = ""  # the trip or fault waiting for its safe state
        self._closed = False
        self.progress = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(),
            TextColumn("{task.percentage:>5.1f}%"), TextColumn("ETA {task.fields[eta]}"),
            TextColumn("{task.fields[live]}"), console=self.console, transient=False,
            auto_refresh=False,
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
                self.progress.stop()
            finally:
                self._lock.release()

    def say(self, text: str) -> None:
        """Print a line from any thread."""
        if self._lock.acquire(timeout=1.0):
            try:
                self.console.print(text)
            finally:
                self._lock.release()

    def __call__(self, event: Event) -> None:
        if self._closed:
            return
        with self._lock:
            self._handle(event)
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
                self.console.print(f"[{lab_time(event.t)}] step {event.index}: adaptive hold "
                                   f"ended after {event.results.get('held_s', 0):.0f} s "
                                   f"({what})", highlight=False)
            if self._task is not None:
                done = event.status == "completed"
                self.progress.update(self._task, completed=1.0 if done else None, eta="-",
                                     live=event.status)
            self._task = None
        elif isinstance(event, StateChanged) and event.reason and not event.new.finished:
            self.console.print(f"[{lab_time(event.t)}] {event.new.value}: {event.reason}")
        elif isinstance(event, InterlockTrip):
            self._headline = f"[bold red]INTERLOCK[/] {event.message}"
        elif isinstance(event, Fault):
            self._headline = f"[bold red]FAULT[/] {event.kind}: {event.message}"
        elif isinstance(event, SafeStopped):
            head = self._headline or f"[bold yellow]ABORTED[/] {event.state.reason}"
            self._headline = ""
            safe = event.state.line()
            safe = safe if event.state.verified else f"[bold red]{safe}[/]"
            where = f"; details: {self.log_path}" if self.log_path else ""
            self.console.print(f"{head}; {safe}{where}", highlight=False, soft_wrap=True)
