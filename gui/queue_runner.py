"""The queue's sequence (issue 28, item 6; ADR 0371): each item rehearsed on the rig's twin,
then run through the window's one run path (``RigDesk.start_run``, the shared run host), the
next one once it completed; the queue stops at the first item that is not run to completion
(bad parameters, a failed rehearsal, a refused, failed or aborted run) and says why.

Everything happens on the GUI thread but the rehearsal, which runs on a thread of its own
(as the protocol panel's) and is collected by a timer; the rig is never touched here.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject, QTimer, Signal

from gelrig.gui import offthread
from gelrig.gui.desk import RigDesk
from gelrig.gui.protocol_panel import Rehearse
from gelrig.gui.queue_items import (
    COMPLETED,
    QUEUED,
    REHEARSING,
    RUNNING,
    STOPPED,
    QueueItem,
    load_queue,
    save_queue,
)
from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import RunState
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rehearsal import RehearsalReport
from gelrig.protocols.runinfo import RunInfo

log = logging.getLogger(__name__)
#: Poll period (ms) of a rehearsal's result.
POLL_MS = 100


class QueueRunner(QObject):
    """The items (kept in ``path`` at every change) and the run of them.

    ``rehearser()`` gives the rehearsal on the connected rig's twin (None: none available);
    ``start_run(procedure, info)`` starts a run as Run does and returns '' or why it could
    not start."""

    changed = Signal()
    said = Signal(str, str)  # line, level ("info", "warning", "error")

    def __init__(self, desk: RigDesk, rehearser: Callable[[], Rehearse | None],
                 start_run: Callable[[Procedure, RunInfo], str], path: Path,
                 parent: QObject | None = None):
        super().__init__(parent)
        self.desk, self.rehearser, self.start_run, self.path = desk, rehearser, start_run, path
        self.items, warning = load_queue(path)
        self.warning = warning
        self.active = False
        self.message = f"{len(self.items)} item(s) kept from before" if self.items else ""
        self._control: RunControl | None = None
        self._outbox: list[object] = []
        self._pending: tuple[QueueItem, Procedure, RunInfo] | None = None
        self._poll = QTimer(self)
        self._poll.setInterval(POLL_MS)
        self._poll.timeout.connect(self._collect)
        desk.run_finished.connect(self._on_run_finished)

    # ---- the items ------------------------------------------------------------------------
    def add(self, items: list[QueueItem]) -> None:
        self.items.extend(items)
        self._changed()

    def remove(self, index: int) -> None:
        if 0 <= index < len(self.items) and self.items[index].state not in (RUNNING,
                                                                              REHEARSING):
            del self.items[index]
            self._changed()

    def clear_finished(self) -> None:
        """Drop the items that ran or where the queue stopped (the waiting ones stay)."""
        self.items = [i for i in self.items if i.state in (QUEUED, RUNNING, REHEARSING)]
        self._changed()

    def _changed(self) -> None:
        try:
            save_queue(self.path, self.items)
        except OSError as exc:
            self.said.emit(f"the queue could not be saved to {self.path}: {exc}", "warning")
        self.changed.emit()

    # ---- the sequence ---------------------------------------------------------------------
    def start(self) -> None:
        """Run the waiting items one after another (from the first waiting one)."""
        if self.active:
            return
        if not any(i.state == QUEUED for i in self.items):
            self._say("nothing queued", "warning")
            return
        self.active = True
        self._next()

    def stop(self) -> None:
        """Start no further item (a run going on goes on; a rehearsal is abandoned)."""
        if not self.active:
            return
        self.active = False
        for item in self.items:
            if item.state == REHEARSING:
                item.state = QUEUED
        if self._control is not None:
            self._control.abort("the queue was stopped")
            self._control = None
        self._poll.stop()
        running = any(i.state == RUNNING for i in self.items)
        self._say("queue stopped: the run going on ends as it would" if running else
                  "queue stopped", "info")
        self._changed()

    def _next(self) -> None:
        if not self.active:
            return
        item = next((i for i in self.items if i.state == QUEUED), None)
        if item is None:
            self.active = False
            done = sum(i.state == COMPLETED for i in self.items)
            self._say(f"queue done: {done} run(s) completed", "info")
            self._changed()
            return
        try:
            procedure, info = item.procedure(), item.info()
        except ConfigError as exc:
            self._halt(item, f"not started: {exc}")
            return
        except Exception as exc:  # a script that no longer imports: said, the queue stops
            self._halt(item, f"not started: {item.path} cannot be loaded "
                             f"({type(exc).__name__}: {exc})")
            return
        spec, rehearse = self.desk.spec, self.rehearser()
        if self.desk.rig is None or spec is None:
            self._halt(item, "not started: connect the rig")
            return
        if procedure.rig != spec.kind:
            self._halt(item, f"not started: it runs on a {procedure.rig} rig; the rig is a "
                             f"{spec.kind} rig")
            return
        if rehearse is None:
            self._halt(item, "not started: no rehearsal on the rig's twin is available, and "
                             "the queue runs only what it rehearsed")
            return
        item.state, item.reason = REHEARSING, ""
        self._say(f"rehearsing {item.label()} on the rig's twin", "info")
        self._changed()
        control = self._control = RunControl()
        outbox: list[object] = []  # the thread touches no Qt object

        def work() -> None:
            try:
                outbox.append(rehearse(procedure, control))
            except Exception as exc:  # the twin could not be built: said, the GUI goes on
                log.warning("queued rehearsal failed to run: %s", exc, exc_info=True)
                outbox.append(f"{type(exc).__name__}: {exc}")

        self._outbox, self._pending = outbox, (item, procedure, info)
        offthread.refuse_qt(work)
        threading.Thread(target=work, name="queue-rehearsal", daemon=True).start()
        self._poll.start()

    def _collect(self) -> None:
        if not self._outbox or self._pending is None:
            return
        self._poll.stop()
        result = self._outbox.pop()
        (item, procedure, info), self._pending = self._pending, None
        self._control = None
        if not self.active or item.state != REHEARSING:
            return  # stopped meanwhile
        if not isinstance(result, RehearsalReport):
            self._halt(item, f"not started: could not rehearse ({result})")
            return
        if not result.ok:
            self._halt(item, f"not started: its rehearsal failed: {result.failure()}")
            return
        why = self.start_run(procedure, info)
        if why:
            self._halt(item, f"not started: {why}")
            return
        item.state, item.run = RUNNING, str(self.desk.run_path or "")
        self._say(f"running {item.label()} (rehearsed) into {item.run}", "info")
        self._changed()

    def _on_run_finished(self, state: RunState, reason: str) -> None:
        item = next((i for i in self.items if i.state == RUNNING), None)
        if item is None:
            return
        if state is RunState.COMPLETED:
            item.state, item.reason = COMPLETED, ""
            self._changed()
            QTimer.singleShot(0, self._next)
        else:
            self._halt(item, f"run {state.value}: {reason}")

    def _halt(self, item: QueueItem, reason: str) -> None:
        """The queue stops at ``item``: why, on the item, in the panel and the log."""
        item.state, item.reason = STOPPED, reason
        was_active, self.active = self.active, False
        position = self.items.index(item) + 1
        line = f"queue stopped at item {position} ({item.label()}): {reason}"
        self._say(line, "error" if was_active else "warning")
        self._changed()

    def _say(self, line: str, level: str) -> None:
        self.message = line
        self.said.emit(line, level)
