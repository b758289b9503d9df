"""The data store as a subscriber of the event stream: events in, run directory out."""

from __future__ import annotations

import contextlib
from dataclasses import asdict

from gelrig.instrument.core.store import RunDirectory, StepWriter, StorageFault
from gelrig.protocols.events import (
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
    let it go on without recording. A storage fault (disk full) raised while samples arrive
    reaches the runner, which stops motion and ends the run failed; one found when a step's
    file is closed is recorded and raised at the next step, and a run that then "completes"
    is recorded as failed (``storage_fault`` in run.json holds the one line).
    """

    def __init__(self, run: RunDirectory):
        self.run = run
        self._writer: StepWriter | None = None
        self._index: int | None = None
        #: the first storage fault's one line, once there was one
        self.fault: str | None = None
        self._rows = 0

    def __call__(self, event: Event) -> None:
        try:
            self._handle(event)
        except StorageFault as exc:
            if self.fault is None:
                self.fault = str(exc)
                with contextlib.suppress(StorageFault):
                    self.run.update(storage_fault=self.fault)
            raise

    def _handle(self, event: Event) -> None:
        if isinstance(event, StepStarted):
            self._close_writer()
            if self.fault is not None:
                raise StorageFault(self.fault)
            self._writer = self.run.open_step(event.index, event.name, event.kind,
                                              event.columns, event.params, event.t)
            self._index = event.index
        elif isinstance(event, Samples):
            if self._writer is not None and event.index == self._index:
                self._writer.append(event.data)
        elif isinstance(event, StepFinished):
            status, results = event.status, dict(event.results)
            try:
                rows = self._close_writer(event.status)
            except StorageFault as exc:  # raised at the next step: the runner stops there
                self.fault = self.fault or str(exc)
                rows = self._rows
                status, results = "failed", {**results, "reason": str(exc)}
            self.run.finish_step(event.index, status, rows, event.t, results)
            if self.fault is not None:
                self.run.update(storage_fault=self.fault)
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
            with contextlib.suppress(StorageFault):
                self._close_writer(event.state.value)
            self.run.release_space()
            if self.fault is not None and event.state.value == "completed":
                self.run.update(status="failed", reason=self.fault, finished=event.t)
            else:
                self.run.update(status=event.state.value, reason=event.reason, finished=event.t)

    def _close_writer(self, status: str | None = None) -> int:
        writer, self._writer, self._index = self._writer, None, None
        if writer is None:
            return 0
        try:
            writer.close(status)
        finally:
            self._rows = writer.rows  # what the file keeps, also after a fault
        return writer.rows
