"""A rehearsal: the whole protocol run in virtual time on the rig's twin, measured.

The twin is the rig with each instrument replaced by its simulator under the same
configuration (built by the composition root: ``gelrig.factory.build_twin``). The same Runner,
preflight, caps and interlocks as a real run run here; instead of a run directory a counting
subscriber listens on the bus and records the figures: the exact lab time of every step, the
travel, the samples and bytes of the recorded columns, and every limit, interlock or fault the
run hits, with where (step, lab time, what). See docs/decisions/0090.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gelrig.instrument.core.units import lab_time
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import (
    Event,
    EventBus,
    Fault,
    Finished,
    InterlockTrip,
    RunState,
    Samples,
    StateChanged,
    StepFinished,
    StepStarted,
)
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rig import Rig
from gelrig.protocols.runner import Runner
from gelrig.protocols.script import Script
from gelrig.protocols.spec import effective_params

log = logging.getLogger(__name__)

#: Columns whose path length is a step's travel: the plate position, the arm's arc.
TRAVEL_COLUMNS = ("position_m", "theta_m")
#: Columns whose range is reported: where the plate went, how low the gap went.
RANGE_COLUMNS = ("position_m", "gap_m")


@dataclass
class StepFigures:
    """What one step did on the twin: status, lab times (s), samples, bytes, travel (m)."""

    index: int
    name: str
    kind: str
    status: str = "not run"
    started: float = math.nan
    finished: float = math.nan
    samples: int = 0
    bytes: int = 0
    travel: float = 0.0
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    columns: tuple[str, ...] = ()
    #: the parameters the step ran with, as ``gelrig plan`` prints them (a script's steps,
    #: which no static plan shows): ``key = value [(default) | (sample)]``
    uses: list[str] = field(default_factory=list)
    #: the step's results (a hold's fits from the twin's data)
    results: dict[str, Any] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Lab time of the step (s); NaN if it never started."""
        return self.finished - self.started


@dataclass(frozen=True)
class LimitHit:
    """A limit, interlock or fault the run hit: in which step, at what lab time, what."""

    index: int | None
    step: str
    t: float
    what: str
    #: "limit" (an interlock trip) or "fault" (a fault or a refusal event)
    kind: str = "limit"


@dataclass
class RehearsalReport:
    """The measured figures of one rehearsal; ``ok`` when every step completed."""

    protocol: str
    state: RunState
    reason: str
    start: float
    end: float
    steps: list[StepFigures]
    hits: list[LimitHit]
    #: the refusal's own line when a step was refused (no "refused before ..." tail)
    refusal: str = ""
    #: the procedure is a script: an exception between steps is the script's own
    script: bool = False

    @property
    def ok(self) -> bool:
        return self.state is RunState.COMPLETED

    @property
    def total(self) -> float:
        """Lab time of the whole run (s), from the first step's start to the end."""
        return self.end - self.start

    @property
    def samples(self) -> int:
        return sum(s.samples for s in self.steps)

    @property
    def bytes(self) -> int:
        return sum(s.bytes for s in self.steps)

    @property
    def travel(self) -> float:
        return sum(s.travel for s in self.steps)

    def failure(self) -> str:
        """One line: the step that failed, when, and why ('' if the rehearsal passed)."""
        if self.ok:
            return ""
        if self.refusal:  # refused before the step moved: the line names its step (a run
            return f"{self.refusal}; refused before anything moves"  # rehearsed refuses first
        if self.reason.startswith("step "):
            return self.reason
        failed = next((s for s in self.steps if s.status not in ("completed", "not run")),
                      None)
        if failed is None:  # between steps: the script's own code (or a replay mismatch)
            if self.script and self.state is RunState.FAILED:
                return f"the script raised {self.reason}"
            return f"{self.state.value}: {self.reason}"
        return (f"step {failed.index} ({failed.name}) at {self.end:.1f} s lab time: "
                f"{self.reason}")

    def lines(self) -> list[str]:
        """The figures for people, one step a line, then the limits hit and the total."""
        out = []
        for s in self.steps:
            if s.status in ("not run", "refused") or math.isnan(s.started):
                out.append(f"{s.index}. {s.name}: {s.status}")
                out += [f"   uses {', '.join(s.uses)}"] if s.uses else []
                continue
            where = "".join(f", {_short(c)} {lo * 1e3:.3f}..{hi * 1e3:.3f} mm"
                            for c, (lo, hi) in s.ranges.items())
            out.append(f"{s.index}. {s.name}: {s.status} in {s.duration:.2f} s "
                       f"({lab_time(s.duration)}) lab time, travel {s.travel * 1e3:.1f} mm"
                       f"{where}; {s.samples:,} samples x {len(s.columns)} columns, "
                       f"{human_bytes(s.bytes)}")
            out += [f"   uses {', '.join(s.uses)}"] if s.uses else []
        for hit in self.hits:
            if not self.ok and self.reason and self.reason in hit.what:
                continue  # the run's end: said once, by failure()
            head = "LIMIT" if hit.kind == "limit" else "FAULT"
            out.append(f"{head} step {hit.index} ({hit.step}) at {hit.t:.1f} s: {hit.what}"
                       if hit.index is not None else f"{head} at {hit.t:.1f} s: {hit.what}")
        verdict = "passed" if self.ok else "FAILED (why: the one line below)"
        out.append(f"Total: {self.total:.2f} s ({lab_time(self.total)}) lab time, travel "
                   f"{self.travel * 1e3:.1f} mm, {self.samples:,} samples, "
                   f"{human_bytes(self.bytes)}; rehearsal {verdict}")
        return out


def _short(column: str) -> str:
    return {"position_m": "plate", "gap_m": "gap"}.get(column, column)


def human_bytes(n: float) -> str:
    """``n`` bytes as B, kB, MB or GB (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError("unreachable")


class Counter:
    """A bus subscriber that counts what a recorder would write, and where limits were hit."""

    def __init__(self, protocol: Procedure):
        self.steps = [StepFigures(i, s.name, s.kind) for i, s in enumerate(protocol.steps)]
        self.hits: list[LimitHit] = []
        self.start = math.nan
        self.end = math.nan
        self.current: StepFigures | None = None
        self._last: dict[str, float] = {}

    def __call__(self, event: Event) -> None:
        if isinstance(event, Samples):
            self._samples(event.data)
        elif isinstance(event, StepStarted):
            figures = self._figures(event.index, event.name, event.kind)
            figures.status, figures.started = "running", event.t
            figures.columns = tuple(event.columns)
            self.current, self._last = figures, {}
        elif isinstance(event, StepFinished):  # also a script's step refused before it began
            figures = self._figures(event.index, event.name, "")
            figures.status, figures.finished = event.status, event.t
            figures.results = dict(event.results)
            self.current = None
        elif isinstance(event, InterlockTrip):
            self._hit(event.t, f"{event.interlock} interlock: {event.message}", "limit")
        elif isinstance(event, Fault):
            self._hit(event.t, f"{event.kind}: {event.message}", "fault")
        elif isinstance(event, StateChanged) and math.isnan(self.start):
            self.start = event.t
        elif isinstance(event, Finished):
            self.end = event.t

    def _figures(self, index: int, name: str, kind: str) -> StepFigures:
        index = max(index, 0)
        while len(self.steps) <= index:  # a script's steps show up as it runs
            self.steps.append(StepFigures(len(self.steps), name, kind))
        return self.steps[index]

    def _hit(self, t: float, what: str, kind: str) -> None:
        step = self.current
        self.hits.append(LimitHit(step.index if step else None, step.name if step else "", t,
                                  what, kind))

    def _samples(self, data: Mapping[str, FloatArray]) -> None:
        """Count a block. Called once per read (thousands of small blocks in a shear ladder):
        the ufuncs are called directly, which is what np.diff, ndarray.sum/min/max compute."""
        figures = self.current
        if figures is None or not data:
            return
        kept = [data[c] for c in figures.columns if c in data] or list(data.values())
        n = len(kept[0])
        if n == 0:
            return
        figures.samples += n
        figures.bytes += sum(v.nbytes if type(v) is np.ndarray else int(np.asarray(v).nbytes)
                             for v in kept)
        for column in TRAVEL_COLUMNS:
            if column in data:
                v = np.asarray(data[column], dtype=float)
                prev = self._last.get(column)
                path = float(np.add.reduce(np.abs(v[1:] - v[:-1])))
                if prev is not None and math.isfinite(prev):
                    path += abs(float(v[0]) - prev)
                figures.travel += path
                self._last[column] = float(v[-1])
        for column in RANGE_COLUMNS:
            if column in data:
                v = np.asarray(data[column], dtype=float)
                lo, hi = float(np.minimum.reduce(v)), float(np.maximum.reduce(v))
                old = figures.ranges.get(column)
                figures.ranges[column] = (lo, hi) if old is None else (min(old[0], lo),
                                                                       max(old[1], hi))


def rehearse(
    rig: Rig, protocol: Procedure, bus: EventBus | None = None,
    control: RunControl | None = None,
) -> RehearsalReport:
    """Run ``protocol`` on ``rig`` (a twin, in virtual time) counting instead of recording;
    the caller builds and closes the rig. Any error ends the rehearsal as a failure."""
    bus = EventBus() if bus is None else bus
    counter = Counter(protocol)
    bus.subscribe(counter)
    runner = Runner(rig, protocol, bus, control, watched=False, rehearsal=True)
    try:
        state = runner.run()
        reason = runner.reason
    except Exception as exc:  # a bug or an unexpected error: report it, do not raise
        state, reason = RunState.FAILED, f"{type(exc).__name__}: {exc}"
        log.error("the rehearsal raised", exc_info=exc)
    start = counter.start if math.isfinite(counter.start) else rig.clock.now()
    end = counter.end if math.isfinite(counter.end) else rig.clock.now()
    known = len(protocol.steps)  # a protocol file's: its static plan prints them
    for index, step in enumerate(runner.sent):
        if index >= known:
            counter._figures(index, step.name, step.kind).uses = effective_params(step)
    return RehearsalReport(protocol.name, state, reason, start, end, counter.steps,
                           counter.hits, runner.refusal, isinstance(protocol, Script))


def describe(report: RehearsalReport) -> dict[str, Any]:
    """The report as plain data (for JSON or a GUI)."""
    return {"protocol": report.protocol, "state": report.state.value, "reason": report.reason,
            "lab_time_s": report.total, "samples": report.samples, "bytes": report.bytes,
            "steps": [{"index": s.index, "name": s.name, "status": s.status,
                       "lab_time_s": s.duration, "samples": s.samples, "bytes": s.bytes,
                       "travel_m": s.travel} for s in report.steps],
            "hits": [{"index": h.index, "step": h.step, "t": h.t, "what": h.what}
                     for h in report.hits]}
