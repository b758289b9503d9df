"""The data store as a subscriber of the event stream: events in, run directory out."""

from __future__ import annotations

from dataclasses import asdict

from instrument.store import RunDirectory, StepWriter
from protocols.events import (
    Event,
    Fault,
    Finished,
    InterlockTrip,
    SafeStopped,
    Samples,
    StateChanged,
    StepFinished,
    StepStarted,
)


class Recorder:
    """Writes every step's samples and the run's story to a RunDirectory.

    Subscribe it as *critical*: a failure to write (disk full) must stop the run rather than
    let it go on without recording.
    """

    def __init__(self, run: RunDirectory):
        self.run = run
        self._writer: StepWriter | None = None
        self._index: int | None = None

    def __call__(self, event: Event) -> None:
        if isinstance(event, StepStarted):
            self._close_writer()
            self._writer = self.run.open_step(event.index, event.name, event.kind,
                                              event.columns, event.params, event.t)
            self._index = event.index
        elif isinstance(event, Samples):
            if self._writer is not None and event.index == self._index:
                self._writer.append(event.data)
        elif isinstance(event, StepFinished):
            rows = self._close_writer({"status": event.status})
            self.run.finish_step(event.index, event.status, rows, event.t, event.results)
        elif isinstance(event, StateChanged):
            self.run.update(status=event.new.value)
        elif isinstance(event, InterlockTrip):
            meta = self.run.read_metadata()
            trip = asdict(event)
            meta["interlock_trips"].append(trip)
            self.run.write_metadata(meta)
        elif isinstance(event, Fault):
            meta = self.run.read_metadata()
            meta.setdefault("faults", []).append({"t": event.t, "kind": event.kind,
                                                  "message": event.message})
            self.run.write_metadata(meta)
        elif isinstance(event, SafeStopped):
            self.run.update(safe_state=event.state.as_dict())
        elif isinstance(event, Finished):
            self._close_writer({"status": event.state.value})
            self.run.update(status=event.state.value, reason=event.reason, finished=event.t)

    def _close_writer(self, attrs: dict[str, str] | None = None) -> int:
        rows = 0
        if self._writer is not None:
            self._writer.close(attrs)
            rows = self._writer.rows
        self._writer = None
        self._index = None
        return rows
