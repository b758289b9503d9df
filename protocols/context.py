"""What a running step sees: the rig, the clock, the event stream, interlocks and control."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Generic, TypeVar

from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import InterlockTripped
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import (
    EventBus,
    InterlockTrip,
    Progress,
    RunState,
    Samples,
    StateChanged,
)
from gelrig.protocols.interlocks import Interlock, check
from gelrig.protocols.rig import RigT

T = TypeVar("T")


class StepContext(Generic[RigT]):
    """Services for one step on its rig: publish samples (interlocks checked on every sample),
    report progress, honour pause at checkpoints and abort at every block, and hand over
    earlier steps' results by type."""

    def __init__(
        self,
        rig: RigT,
        bus: EventBus,
        control: RunControl,
        index: int,
        outcomes: Mapping[int, object] | None = None,
        watched: bool = True,
        rehearsal: bool = False,
    ):
        self.rig: RigT = rig
        self.clock: Clock = rig.clock
        self.bus = bus
        self.control = control
        self.index = index
        self.outcomes = outcomes or {}
        self.interlocks: tuple[Interlock, ...] = ()
        self.samples_published = 0
        #: someone watches the run (CLI, GUI); False in a rehearsal: work done only for the
        #: display (live refits of a fixed hold) is skipped, nothing that steers the run
        self.watched = watched
        #: the run is a rehearsal on the twin (``gelrig plan``, ``gelrig run``'s check): a step
        #: gives the results a script reads (a hold's fits) from a thinned copy of its data
        self.rehearsal = rehearsal

    def earlier(self, kind: type[T]) -> T | None:
        """The latest earlier step's result of type ``kind`` (e.g. a contact search's), or
        None if no earlier step produced one."""
        for index in sorted((i for i in self.outcomes if i < self.index), reverse=True):
            result = self.outcomes[index]
            if isinstance(result, kind):
                return result
        return None

    def emit(self, data: Mapping[str, FloatArray]) -> None:
        """Publish a block of samples; on an interlock trip stop motion first, publish the
        block up to the tripping sample, then raise InterlockTripped."""
        trip = check(self.interlocks, data)
        if trip is None:
            self.bus.publish(Samples(self.clock.now(), self.index, dict(data)))
            self.samples_published += len(next(iter(data.values()), ()))
            return
        self.rig.stop_all()
        head = {k: v[: trip.index + 1] for k, v in data.items()}
        self.bus.publish(Samples(self.clock.now(), self.index, head))
        il = trip.interlock
        self.bus.publish(InterlockTrip(self.clock.now(), il.name, trip.value, il.limit, il.unit,
                                       trip.message))
        raise InterlockTripped(trip.message)

    def progress(
        self, fraction: float, elapsed: float, remaining: float, message: str = "",
        **values: float,
    ) -> None:
        self.bus.publish(Progress(self.clock.now(), self.index, min(max(fraction, 0.0), 1.0),
                                  elapsed, max(remaining, 0.0), message, values))

    def tick(self) -> None:
        """Called on every block: raises Aborted at once if an abort was requested."""
        self.control.raise_if_aborted()

    def checkpoint(self) -> None:
        """A point where nothing moves: a requested pause takes effect here."""
        self.control.raise_if_aborted()
        if not self.control.pause_requested:
            return
        self.rig.stop_all()
        self.bus.publish(StateChanged(self.clock.now(), RunState.RUNNING, RunState.PAUSED,
                                      "paused at a checkpoint"))
        self.control.wait_resumed()
        self.bus.publish(StateChanged(self.clock.now(), RunState.PAUSED, RunState.RUNNING,
                                      "resumed"))
