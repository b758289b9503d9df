"""The runner's event stream, carried from the rig thread into the GUI thread.

Samples go straight into the run's growing buffers (no signal per block; the plots redraw on
their own timer); progress is coalesced to the newest; the rare events (step started or
finished, state changes, interlock trips, faults, the end) cross as queued Qt signals, in
order.
"""

from __future__ import annotations

import threading

from PySide6.QtCore import QObject, Signal

from gelrig.gui.rundata import RunData
from gelrig.protocols.events import Event, Progress, Samples, StepFinished, StepStarted


class EventBridge(QObject):
    """An event-bus subscriber that is safe to call from the runner's thread."""

    received = Signal(object)

    def __init__(self, data: RunData, parent: QObject | None = None):
        super().__init__(parent)
        self.data = data
        self._lock = threading.Lock()
        self._progress: Progress | None = None

    def __call__(self, event: Event) -> None:
        if isinstance(event, Samples):
            self.data.append(event.index, event.data)
            return
        if isinstance(event, Progress):
            with self._lock:
                self._progress = event
            return
        if isinstance(event, StepStarted):
            self.data.begin_step(event.index, event.name, event.kind, event.columns)
        elif isinstance(event, StepFinished):
            self.data.finish_step(event.index, event.status, event.results)
        self.received.emit(event)

    def take_progress(self) -> Progress | None:
        """The newest progress since the last call (None if there was none)."""
        with self._lock:
            progress, self._progress = self._progress, None
        return progress
