"""The runner: executes a protocol's steps on a rig and tells the event stream everything.

Order on the way out of any trouble is fixed: stop all motion and read it back (the rig's
safe stop, ADR 0070), then record, then report. Abort (from the CLI, the GUI or a test) takes
effect at the next sample block; pause at the next checkpoint; an interlock trip stops motion
within one sample and ends the run; a watchdog faults a run that records no data for too
long.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping
from typing import Any, NoReturn

from gelrig.instrument.core.errors import ConfigError, GelrigError, InterlockTripped, LimitError
from gelrig.protocols.bounds import MAX_STEPS, run_bound_error
from gelrig.protocols.context import StepContext
from gelrig.protocols.control import Aborted, RunControl
from gelrig.protocols.events import (
    EventBus,
    Fault,
    Finished,
    Note,
    RunState,
    SafeStopped,
    StateChanged,
    StepFinished,
    StepStarted,
)
from gelrig.protocols.fence import FenceClosed
from gelrig.protocols.origin import origin
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rig import Rig
from gelrig.protocols.safestop import SafeState
from gelrig.protocols.spec import Step
from gelrig.protocols.steps.base import StepPlan, StepResult
from gelrig.protocols.watchdog import Watchdog

log = logging.getLogger(__name__)


class RunEnded(BaseException):
    """A step ended the run short (abort, trip, fault): motion was stopped and the end
    recorded; raised through the procedure (a script's code too) to unwind it. A
    BaseException, like KeyboardInterrupt, so that a script's ``except Exception`` cannot
    swallow it and go on moving."""

    def __init__(self, state: RunState, reason: str):
        super().__init__(reason)
        self.state = state


class ReplayMismatch(GelrigError):
    """A resumed script asks for a different step than the run recorded at that place."""


class Runner:
    """Runs one procedure (a protocol file or a script, :mod:`gelrig.protocols.procedure`) on one
    rig. ``completed`` holds the results of steps already done, by index: a resumed run does
    not run them again, and hands their stored results to whoever asks (later steps, the
    script)."""

    def __init__(
        self,
        rig: Rig,
        protocol: Procedure,
        bus: EventBus | None = None,
        control: RunControl | None = None,
        completed: Mapping[int, Mapping[str, Any]] | None = None,
        watched: bool = True,
        rehearsal: bool = False,
    ):
        if protocol.rig != rig.kind or not all(isinstance(rig, s.definition.rig)
                                               for s in protocol.steps):
            raise GelrigError(f"protocol {protocol.name!r} runs on a {protocol.rig} rig, "
                              f"not on this {rig.kind} rig")
        self.rig = rig
        self.protocol = protocol
        self.watched = watched  # see StepContext.watched
        self.rehearsal = rehearsal  # see StepContext.rehearsal
        #: every step the procedure sent, in order (what ``gelrig plan`` shows a script's)
        self.sent: list[Step] = []
        self.bus = bus or EventBus()
        self.control = control or RunControl()
        #: what each finished step recorded (run.json's tables), by step index
        self.results: dict[int, Mapping[str, Any]] = dict(completed or {})
        #: the same, typed: what later steps read through ``StepContext.earlier``
        self.outcomes: dict[int, object] = {
            i: protocol.steps[i].definition.Result.from_dict(table)
            for i, table in self.results.items() if i < len(protocol.steps)}
        #: name and kind of each step a resumed run completed before (a replayed script
        #: must ask for the same), by index
        self.recorded: dict[int, tuple[str, str]] = {}
        self.state = RunState.IDLE
        self.reason = ""
        #: set once the run is on its way out (the safe stop has begun)
        self.ending = False
        #: what the safe stop verified, if the run ended short
        self.safe_state: SafeState | None = None
        #: index of the next step the procedure sends
        self.next_index = 0
        #: steps this attempt started (0: nothing of it moved; a replayed step does not count)
        self.started = 0
        #: the refusal's line (``step 1 (x): speed ... above ...``) when the run was refused
        self.refusal = ""
        self._watchdog: Watchdog | None = None
        #: the plans of the steps this run runs, for the bounds on a run (protocols/bounds.py)
        self._planned: list[tuple[str, StepPlan]] = []

    def preflight(self) -> list[str]:
        """Why the rig's caps would refuse a pending step known up front, before anything
        moves: one line per problem, naming the step (``step 1 (ladder): ...``)."""
        problems = []
        earlier: tuple[type[Any], ...] = ()
        self._planned = []
        for index, step in enumerate(self.protocol.steps):
            if index not in self.results:
                problems += [f"step {index} ({step.name}): {why}" for why in
                             step.definition.preflight(step.params, self.rig, earlier)]
                self._planned.append(self._plan(index, step))
            earlier += (step.definition.Result,)
        beyond = run_bound_error(self._planned)
        if beyond is not None:
            problems.append(beyond.line())
        return problems

    def _plan(self, index: int, step: Step) -> tuple[str, StepPlan]:
        return f"step {index} ({step.name})", step.definition.plan(step.params, self.rig.limits)

    def _beyond(self, index: int, step: Step) -> str | None:
        """Why a step decided as the run goes (a script's) takes the run beyond a bound of
        protocols/bounds.py (its steps so far, their samples, their lab time), or None."""
        if index >= MAX_STEPS:
            return f"step {index + 1:,} of the run; at most {MAX_STEPS} steps per run"
        self._planned.append(self._plan(index, step))
        beyond = run_bound_error(self._planned)
        return beyond.line() if beyond is not None else None

    def _set_state(self, new: RunState, reason: str = "") -> None:
        old, self.state = self.state, new
        self.bus.publish(StateChanged(self.rig.clock.now(), old, new, reason))

    def run(self) -> RunState:
        """Execute every step not yet completed; returns the final state."""
        watchdog = self._watchdog = Watchdog(self.control, self.rig.limits.watchdog,
                                             thread=threading.current_thread())
        watchdog.active = False  # armed by each step (a script's code before it is not)
        unsubscribe = self.bus.subscribe(watchdog)
        watchdog.start()
        try:
            return self._run()
        finally:
            watchdog.stop()
            unsubscribe()
            self._watchdog = None

    def _run(self) -> RunState:
        clock = self.rig.clock
        refused = self.preflight()
        if refused:  # a cap or a missing earlier result: refused before anything moves
            return self._refuse(None, "", refused[0])
        self._set_state(RunState.RUNNING)
        try:
            self.protocol.drive(self)
        except RunEnded:
            return self.state
        except ReplayMismatch as exc:  # nothing of this attempt moved yet
            return self._end(None, "", RunState.FAILED, "failed", str(exc),
                             Fault(clock.now(), type(exc).__name__, str(exc)))
        except ConfigError as exc:  # the script's own check of its input: refused, not a fault
            if self.ending:
                raise
            where = origin(exc)
            log.info("the protocol refused its input%s", f" at {where}" if where else "",
                     exc_info=exc)
            return self._refuse(None, "", f"{exc}" + (f" (at {where})" if where else ""))
        except Exception as exc:  # the procedure itself (a script's code) raised
            if self.ending:
                raise
            where = origin(exc)
            log.error("the protocol raised%s", f" at {where}" if where else "", exc_info=exc)
            message = f"{exc}" + (f" (at {where})" if where else "")
            return self._end(None, "", RunState.FAILED, "failed",
                             f"{type(exc).__name__}: {message}",
                             Fault(clock.now(), type(exc).__name__, message))
        except BaseException as exc:  # Ctrl-C without our handler (a script, a notebook)
            if not self.ending:
                self._interrupted(None, "", exc)
            raise
        if self.ending:  # the procedure went on after the run ended (it caught RunEnded)
            return self.state
        self.reason = "all steps completed"
        self._set_state(RunState.COMPLETED)
        self.bus.publish(Finished(clock.now(), RunState.COMPLETED, self.reason))
        return self.state

    def checkpoint(self) -> None:
        """A point between steps where a requested pause takes effect (nothing moves)."""
        StepContext[Any](self.rig, self.bus, self.control, self.next_index, self.outcomes,
                         self.watched, self.rehearsal).checkpoint()

    def note(self, text: str) -> None:
        """A line for people (a script's ``run.log``): in the run's log (logger
        ``gelrig.script``) and on the event stream, where a console view shows it."""
        logging.getLogger("gelrig.script").info("%s", text)
        self.bus.publish(Note(self.rig.clock.now(), text))

    def step(self, step: Step) -> StepResult:
        """Run ``step`` as the next step of the run and return its typed result; a step a
        resumed run completed before is not run again (its stored result comes back, and a
        script that now asks for another step there is refused: :class:`ReplayMismatch`).
        A step that ends the run short raises :class:`RunEnded` once motion is stopped."""
        if self.ending:
            raise RunEnded(self.state, self.reason)
        index = self.next_index
        self.next_index += 1
        self.sent.append(step)
        if index in self.results:
            return self._replay(index, step)
        if self._watchdog is not None:  # a script's own work between steps is not silence
            self._watchdog.active = True
        try:
            return self._step(index, step)
        finally:
            if self._watchdog is not None:
                self._watchdog.active = False

    def _step(self, index: int, step: Step) -> StepResult:
        clock = self.rig.clock
        if index >= len(self.protocol.steps):  # decided as the run goes: check it now
            earlier = tuple(type(o) for i, o in sorted(self.outcomes.items())
                            if i < index and isinstance(o, StepResult))
            refused = step.definition.preflight(step.params, self.rig, earlier)
            beyond = None if refused else self._beyond(index, step)
            refused += [beyond] if beyond is not None else []
            if refused:
                self._refuse(index, step.name, f"step {index} ({step.name}): {refused[0]}")
                raise RunEnded(self.state, self.reason)
        ctx = StepContext[Any](self.rig, self.bus, self.control, index, self.outcomes,
                               self.watched, self.rehearsal)
        fence = self.rig.fence
        try:
            ctx.checkpoint()
            self.started += 1
            self.bus.publish(StepStarted(clock.now(), index, step.name, step.kind,
                                         step.params.to_table(), step.definition.columns))
            with fence.arm(self._fault_first):
                outcome = step.definition.run(ctx, step.params)
        except BaseException as caught:
            # the first instrument fault, not what the step's cleanup raised after it
            exc = fence.cause or caught
            if isinstance(exc, FenceClosed) and self.control.abort_requested:
                exc = Aborted(self.control.abort_reason)  # ended from outside meanwhile
            self._step_ended(index, step, exc)
            raise
        results = outcome.as_dict()
        self.outcomes[index] = outcome
        self.results[index] = results
        self.bus.publish(StepFinished(clock.now(), index, step.name, "completed", results))
        return outcome

    def _step_ended(self, index: int, step: Step, exc: BaseException) -> None:
        """The way out of a step that raised ``exc``: raises :class:`RunEnded` once the end
        is recorded (a BaseException such as Ctrl-C is recorded and left to propagate)."""
        clock = self.rig.clock
        if isinstance(exc, Aborted):
            reason = str(exc) or "abort requested"
            if self.control.fault_kind:  # the watchdog: a fault, not a person's abort
                self._end(index, step.name, RunState.FAILED, "failed", reason,
                          Fault(clock.now(), self.control.fault_kind, reason))
            else:
                self._end(index, step.name, RunState.ABORTED, "aborted", reason)
            raise RunEnded(self.state, reason) from None
        if isinstance(exc, InterlockTripped):
            self._end(index, step.name, RunState.ABORTED, "aborted", str(exc))
            raise RunEnded(self.state, str(exc)) from None
        if isinstance(exc, Exception):  # an instrument's error, or a bug in a step kind
            message = str(exc)
            if not isinstance(exc, GelrigError):
                log.error("step %d (%s) raised", index, step.name, exc_info=exc)
                where = origin(exc)
                message += f" (at {where})" if where else ""
            reason = f"{type(exc).__name__}: {message}"
            self._end(index, step.name, RunState.FAILED, "failed", reason,
                      Fault(clock.now(), type(exc).__name__, message))
            raise RunEnded(self.state, reason) from None
        self._interrupted(index, step.name, exc)  # Ctrl-C outside our handlers: stop first

    def refuse(self, name: str, problem: str) -> NoReturn:
        """The procedure's next step (``name``) is not valid (a script's value out of range,
        an unknown field or kind): refused before it moves; raises :class:`RunEnded`."""
        if self.ending:
            raise RunEnded(self.state, self.reason)
        index = self.next_index
        self.next_index += 1
        self._refuse(index, name, f"step {index} ({name}): {problem}")
        raise RunEnded(self.state, self.reason)

    def _refuse(self, index: int | None, name: str, problem: str) -> RunState:
        """A step the caps, the bounds or a missing earlier result refuse, before it moves:
        the run ends ``refused``. Before any step of this attempt started nothing moved: no
        safe stop (the rig is as it was), and a front end may discard the run folder; after
        one, the rig is stopped and made safe first and the recorded steps are kept."""
        clock = self.rig.clock
        self.refusal = problem
        if self.started:
            reason = (f"{problem}; refused before it moved (the data of the {self.started} "
                      f"step{'s' if self.started > 1 else ''} before it are kept)")
            return self._end(index, name, RunState.REFUSED, "refused", reason,
                             Fault(clock.now(), LimitError.__name__, reason))
        self.ending = True
        self.reason = f"{problem}; refused before anything moves"
        log.error("run refused: %s", self.reason)
        self.bus.publish(Fault(clock.now(), LimitError.__name__, self.reason))
        if index is not None:  # what a rehearsal counts: the step that was refused
            self.bus.publish(StepFinished(clock.now(), index, name, "refused",
                                          {"reason": self.reason}))
        self._set_state(RunState.REFUSED, self.reason)
        self.bus.publish(Finished(clock.now(), RunState.REFUSED, self.reason))
        return self.state

    def _fault_first(self, instrument: str, exc: BaseException) -> SafeState:
        """The fence's call on a step's first instrument fault: the safe stop, now, before
        the step's own cleanup talks to the instruments (protocols/fence.py)."""
        self.ending = True
        reason = f"{type(exc).__name__}: {exc}"
        log.error("%s failed: %s; safe stop first", instrument, reason)
        return self.rig.safe_stop(reason, faulted=instrument)

    def _replay(self, index: int, step: Step) -> StepResult:
        """The stored result of a step a resumed run completed before."""
        known = self.recorded.get(index)
        if known is not None and known != (step.name, step.kind):
            raise ReplayMismatch(
                f"step {index}: the run recorded {known[0]!r} ({known[1]}) here, the protocol "
                f"now asks for {step.name!r} ({step.kind}); a resume replays the same steps "
                "in the same order (start a new run for a changed protocol)")
        outcome = self.outcomes.get(index)
        if outcome is None:
            outcome = step.definition.Result.from_dict(self.results[index])
            self.outcomes[index] = outcome
        return outcome  # type: ignore[return-value]

    def _interrupted(self, index: int | None, name: str, exc: BaseException) -> None:
        """KeyboardInterrupt (aborted) or another BaseException (failed): stop first."""
        if isinstance(exc, KeyboardInterrupt):
            self._end(index, name, RunState.ABORTED, "aborted", "interrupted (Ctrl-C)")
        else:
            self._end(index, name, RunState.FAILED, "failed", f"{type(exc).__name__}: {exc}",
                      Fault(self.rig.clock.now(), type(exc).__name__, str(exc)))

    def _end(self, index: int | None, name: str, state: RunState, status: str, reason: str,
             fault: Fault | None = None) -> RunState:
        """The way out of a run that ended short: safe stop first (stop, read back, safe
        position), then the fault, the safe state, the step's end (``index`` None: it ended
        between steps) and the run's."""
        self.ending = True
        if fault is not None:
            log.error("run %s: %s", status, reason)
        fence = self.rig.fence
        safe = fence.safe_state  # run at the fault already (safe stop first), or from outside
        fence.safe_state = fence.cause = None
        if safe is None:
            safe = self.rig.safe_stop(reason)
        safe.reason = reason
        self.safe_state = safe
        log.log(logging.INFO if safe.verified else logging.ERROR, "safe stop: %s", safe.line())
        clock = self.rig.clock
        self.reason = reason
        if fault is not None:
            self.bus.publish(fault)
        self.bus.publish(SafeStopped(clock.now(), safe))
        if index is not None:
            self.bus.publish(StepFinished(clock.now(), index, name, status, {"reason": reason}))
        self._set_state(state, reason)
        self.bus.publish(Finished(clock.now(), state, reason))
        return state
