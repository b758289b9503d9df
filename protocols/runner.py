"""The runner: executes a protocol's steps on a rig and tells the event stream everything.

Order on the way out of any trouble is fixed: stop all motion and read it back (the rig's
safe stop, ADR 0070), then record, then report. Abort (from the CLI, the GUI or a test) takes
effect at the next sample block; pause at the next checkpoint; an interlock trip stops motion
within one sample and ends the run; a watchdog faults a run that records no data for too
long.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from instrument.errors import GelrigError, InterlockTripped, LimitError
from protocols.context import StepContext
from protocols.control import Aborted, RunControl
from protocols.events import (
    EventBus,
    Fault,
    Finished,
    RunState,
    SafeStopped,
    StateChanged,
    StepFinished,
    StepStarted,
)
from protocols.rig import Rig
from protocols.safestop import SafeState
from protocols.spec import ProtocolSpec
from protocols.watchdog import Watchdog

log = logging.getLogger(__name__)


class Runner:
    """Runs one protocol on one rig. ``completed`` holds the results of steps already done
    (a resumed run skips them and hands their results to later steps)."""

    def __init__(
        self,
        rig: Rig,
        protocol: ProtocolSpec,
        bus: EventBus | None = None,
        control: RunControl | None = None,
        completed: Mapping[int, Mapping[str, Any]] | None = None,
        watched: bool = True,
    ):
        if protocol.rig != rig.kind or not all(isinstance(rig, s.definition.rig)
                                               for s in protocol.steps):
            raise GelrigError(f"protocol {protocol.name!r} runs on a {protocol.rig} rig, "
                              f"not on this {rig.kind} rig")
        self.rig = rig
        self.protocol = protocol
        self.watched = watched  # see StepContext.watched
        self.bus = bus or EventBus()
        self.control = control or RunControl()
        #: what each finished step recorded (run.json's tables), by step index
        self.results: dict[int, Mapping[str, Any]] = dict(completed or {})
        #: the same, typed: what later steps read through ``StepContext.earlier``
        self.outcomes: dict[int, object] = {
            i: protocol.steps[i].definition.Result.from_dict(table)
            for i, table in self.results.items() if i < len(protocol.steps)}
        self.state = RunState.IDLE
        self.reason = ""
        #: set once the run is on its way out (the safe stop has begun)
        self.ending = False
        #: what the safe stop verified, if the run ended short
        self.safe_state: SafeState | None = None

    def preflight(self) -> list[str]:
        """Why the rig's caps would refuse a pending step, known before anything moves:
        one line per problem, naming the step (``step 1 (ladder): ...``)."""
        problems = []
        earlier: tuple[type[Any], ...] = ()
        for index, step in enumerate(self.protocol.steps):
            if index not in self.results:
                problems += [f"step {index} ({step.name}): {why}" for why in
                             step.definition.preflight(step.params, self.rig, earlier)]
            earlier += (step.definition.Result,)
        return problems

    def _set_state(self, new: RunState, reason: str = "") -> None:
        old, self.state = self.state, new
        self.bus.publish(StateChanged(self.rig.clock.now(), old, new, reason))

    def run(self) -> RunState:
        """Execute every step not yet completed; returns the final state."""
        watchdog = Watchdog(self.control, self.rig.limits.watchdog)
        unsubscribe = self.bus.subscribe(watchdog)
        watchdog.start()
        try:
            return self._run()
        finally:
            watchdog.stop()
            unsubscribe()

    def _run(self) -> RunState:
        clock = self.rig.clock
        refused = self.preflight()
        if refused:  # a cap or a missing earlier result: fail before anything moves
            self.reason = f"{refused[0]}; refused before anything moves"
            self.bus.publish(Fault(clock.now(), LimitError.__name__, self.reason))
            self._set_state(RunState.FAILED, self.reason)
            self.bus.publish(Finished(clock.now(), RunState.FAILED, self.reason))
            return self.state
        self._set_state(RunState.RUNNING)
        for index, step in enumerate(self.protocol.steps):
            if index in self.results:
                continue
            ctx = StepContext[Any](self.rig, self.bus, self.control, index, self.outcomes,
                                   self.watched)
            try:
                ctx.checkpoint()
                self.bus.publish(StepStarted(clock.now(), index, step.name, step.kind,
                                             step.params.to_table(), step.definition.columns))
                outcome = step.definition.run(ctx, step.params)
            except Aborted as exc:
                reason = str(exc) or "abort requested"
                if self.control.fault_kind:  # the watchdog: a fault, not a person's abort
                    return self._end(index, step.name, RunState.FAILED, "failed", reason,
                                     Fault(clock.now(), self.control.fault_kind, reason))
                return self._end(index, step.name, RunState.ABORTED, "aborted", reason)
            except InterlockTripped as exc:
                return self._end(index, step.name, RunState.ABORTED, "aborted", str(exc))
            except GelrigError as exc:
                return self._end(index, step.name, RunState.FAILED, "failed",
                                 f"{type(exc).__name__}: {exc}",
                                 Fault(clock.now(), type(exc).__name__, str(exc)))
            except BaseException as exc:  # Ctrl-C outside our handlers, a bug: stop first
                log.error("step %d (%s) raised", index, step.name, exc_info=exc)
                self._end(index, step.name, RunState.FAILED, "failed",
                          f"{type(exc).__name__}: {exc}",
                          Fault(clock.now(), type(exc).__name__, str(exc)))
                raise
            results = outcome.as_dict()
            self.outcomes[index] = outcome
            self.results[index] = results
            self.bus.publish(StepFinished(clock.now(), index, step.name, "completed", results))
        self.reason = "all steps completed"
        self._set_state(RunState.COMPLETED)
        self.bus.publish(Finished(clock.now(), RunState.COMPLETED, self.reason))
        return self.state

    def _end(self, index: int, name: str, state: RunState, status: str, reason: str,
             fault: Fault | None = None) -> RunState:
        """The way out of a run that ended short: safe stop first (stop, read back, safe
        position), then the fault, the safe state, the step's end and the run's."""
        self.ending = True
        if fault is not None:
            log.error("run %s: %s", status, reason)
        safe = self.rig.safe_stop(reason)
        self.safe_state = safe
        log.log(logging.INFO if safe.verified else logging.ERROR, "safe stop: %s", safe.line())
        clock = self.rig.clock
        self.reason = reason
        if fault is not None:
            self.bus.publish(fault)
        self.bus.publish(SafeStopped(clock.now(), safe))
        self.bus.publish(StepFinished(clock.now(), index, name, status, {"reason": reason}))
        self._set_state(state, reason)
        self.bus.publish(Finished(clock.now(), state, reason))
        return state
