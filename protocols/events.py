"""The one event stream of a run: typed events and a bus that subscribers listen on.

The runner publishes; the CLI's progress bars, the data store and the GUI's plots subscribe.
None of them reaches into another (design.md principle 7).
"""

from __future__ import annotations

import enum
import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.safestop import SafeState

if TYPE_CHECKING:  # the live fit (and scipy.optimize) only when a hold fits
    from gelrig.instrument.analysis.live_fit import LiveFitState

log = logging.getLogger(__name__)


class RunState(enum.Enum):
    """Where a run is."""

    IDLE = "idle"
    RUNNING = "running"
    PAUSED = "paused"
    ABORTING = "aborting"
    COMPLETED = "completed"
    ABORTED = "aborted"
    FAILED = "failed"
    #: a step the rig's caps or the run's bounds refuse, ended before it moved (exit 2)
    REFUSED = "refused"

    @property
    def finished(self) -> bool:
        return self in (RunState.COMPLETED, RunState.ABORTED, RunState.FAILED,
                        RunState.REFUSED)


@dataclass(frozen=True)
class Event:
    """Base of every event; ``t`` is the clock time (s) at which it was published."""

    t: float


@dataclass(frozen=True)
class StepStarted(Event):
    """Step ``index`` begins: its parameters (TOML keys, SI values; what run.json records)
    and the columns, with units, of the samples it will publish."""

    index: int
    name: str
    kind: str
    params: Mapping[str, Any]
    #: column name -> unit of the samples this step will publish
    columns: Mapping[str, str]


@dataclass(frozen=True)
class Samples(Event):
    """A block of samples of the current step, one array per column (SI units)."""

    index: int
    data: Mapping[str, FloatArray]

    def __len__(self) -> int:
        return len(next(iter(self.data.values()))) if self.data else 0


@dataclass(frozen=True)
class Progress(Event):
    """How far step ``index`` is (``fraction`` 0..1; ``elapsed`` and ``remaining`` in lab
    seconds), a line for people, and live values by column-like name (SI)."""

    index: int
    fraction: float
    elapsed: float
    remaining: float
    message: str = ""
    values: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FitUpdate(Event):
    """A refit of the live relaxation fit during step ``index``'s hold
    (``gelrig.instrument.analysis.live_fit.LiveFitState``: parameters, standard errors, terms
    resolved, each
    time constant's relative standard error now and forecast at the planned end); ``met``:
    this refit meets the adaptive hold's target, ``ending``: the hold ends on it."""

    index: int
    state: LiveFitState
    met: bool = False
    ending: bool = False


@dataclass(frozen=True)
class StepFinished(Event):
    """Step ``index`` ended; ``results`` is its result as run.json records it (on failure or
    abort: the reason)."""

    index: int
    name: str
    status: str  # "completed" | "aborted" | "failed" | "refused"
    results: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StateChanged(Event):
    """The run moved from ``old`` to ``new`` (running, paused, ...), and why."""

    old: RunState
    new: RunState
    reason: str = ""


@dataclass(frozen=True)
class InterlockTrip(Event):
    """An interlock tripped: motion was stopped before this was published. ``value`` is the
    sample that crossed ``limit`` (both in ``unit``)."""

    interlock: str
    value: float
    limit: float
    unit: str
    message: str


@dataclass(frozen=True)
class Fault(Event):
    """A fault ended the run (``kind``: the error's type name); the stop was sent first, and a
    :class:`SafeStopped` follows with what was verified."""

    kind: str
    message: str


@dataclass(frozen=True)
class SafeStopped(Event):
    """The run ended short: motion was stopped and read back, and the sample put in its safe
    state where the rig file asks; ``state`` says what was verified (its ``line()`` is what
    people see)."""

    state: SafeState


@dataclass(frozen=True)
class Note(Event):
    """A line a procedure wrote for people (``run.log``): shown by the console view, kept
    in the run's log."""

    text: str


@dataclass(frozen=True)
class Finished(Event):
    """The run is over: completed, aborted or failed, and why. Always the last event."""

    state: RunState
    reason: str = ""


Subscriber = Callable[[Event], None]


class EventBus:
    """Synchronous publish/subscribe, safe to use from several threads.

    A *critical* subscriber (the data store) propagates its errors to the publisher, which
    stops the run; an ordinary one (a plot, a progress bar) is logged and kept, so a display
    can never lose data.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._subscribers: list[tuple[Subscriber, bool]] = []

    def subscribe(self, subscriber: Subscriber, critical: bool = False) -> Callable[[], None]:
        """Add a subscriber; returns a function that removes it."""
        entry = (subscriber, critical)
        with self._lock:
            self._subscribers.append(entry)

        def unsubscribe() -> None:
            with self._lock:
                if entry in self._subscribers:
                    self._subscribers.remove(entry)

        return unsubscribe

    def publish(self, event: Event) -> None:
        with self._lock:
            subscribers = list(self._subscribers)
        for subscriber, critical in subscribers:
            if critical:
                subscriber(event)
                continue
            try:
                subscriber(event)
            except Exception as exc:  # a display: one line for the user, details for debugging
                log.error("a display (%s) failed on %s: %s: %s", type(subscriber).__name__,
                          type(event).__name__, type(exc).__name__, exc)
                log.debug("subscriber failure", exc_info=True)


def as_columns(**columns: FloatArray | float) -> dict[str, FloatArray]:
    """Build a Samples payload, turning scalars into one-element arrays."""
    return {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in columns.items()}
