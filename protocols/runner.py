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
from protocols.procedure import Procedure
from protocols.rig import Rig
from protocols.safestop import SafeState
from protocols.spec import Step
from protocols.steps.base import StepResult
from protocols.watchdog import Watchdog

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
    """Runs one procedure (a protocol file or a script, :mod:`protocols.procedure`) on one
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
        self._watchdog: Watchdog | None = None

    def preflight(self) -> list[str]:
        """Why the rig's caps would refuse a pending step known up front, before anything
        moves: one line per problem, naming the step (``step 1 (ladder): ...``)."""
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
        watchdog = self._watchdog = Watchdog(self.control, self.rig.limits.watchdog)
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
        if refused:  # a cap or a missing earlier result: fail before anything moves
            self.reason = f"{refused[0]}; refused before anything moves"
            self.bus.publish(Fault(clock.now(), LimitError.__name__, self.reason))
            self._set_state(RunState.FAILED, self.reason)
            self.bus.publish(Finished(clock.now(), RunState.FAILED, self.reason))
            return self.state
        self._set_state(RunState.RUNNING)
        try:
            self.protocol.drive(self)
        except RunEnded:
            return self.state
        except ReplayMismatch as exc:  # nothing of this attempt moved yet
            return self._end(None, "", RunState.FAILED, "failed", str(exc),
                             Fault(clock.now(), type(exc).__name__, str(exc)))
        except Exception as exc:  # the procedure itself (a script's code) raised
            if self.ending:
                raise
            where = _origin(exc)
            log.error("the protocol raised%s", f" at {where}" if where else "", exc_info=exc)
            reason = f"{type(exc).__name__}: {exc}" + (f" (at {where})" if where else "")
            return self._end(None, "", RunState.FAILED, "failed", reason,
                             Fault(clock.now(), type(exc).__name__, reason))
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
                         self.watched).checkpoint()

    def step(self, step: Step) -> StepResult:
        """Run ``step`` as the next step of the run and return its typed result; a step a
        resumed run completed before is not run again (its stored result comes back, and a
        script that now asks for another step there is refused: :class:`ReplayMismatch`).
        A step that ends the run short raises :class:`RunEnded` once motion is stopped."""
        if self.ending:
            raise RunEnded(self.state, self.reason)
        index = self.next_index
        self.next_index += 1
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
            if refused:
                reason = f"step {index} ({step.name}): {refused[0]}; refused before it moved"
                self._end(index, step.name, RunState.FAILED, "failed", reason,
                          Fault(clock.now(), LimitError.__name__, reason))
                raise RunEnded(self.state, reason)
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
                self._end(index, step.name, RunState.FAILED, "failed", reason,
                          Fault(clock.now(), self.control.fault_kind, reason))
            else:
                self._end(index, step.name, RunState.ABORTED, "aborted", reason)
            raise RunEnded(self.state, reason) from None
        except InterlockTripped as exc:
            self._end(index, step.name, RunState.ABORTED, "aborted", str(exc))
            raise RunEnded(self.state, str(exc)) from None
        except Exception as exc:  # an instrument's error, or a bug in a step kind
            reason = f"{type(exc).__name__}: {exc}"
            if not isinstance(exc, GelrigError):
                log.error("step %d (%s) raised", index, step.name, exc_info=exc)
                where = _origin(exc)
                reason += f" (at {where})" if where else ""
            self._end(index, step.name, RunState.FAILED, "failed", reason,
                      Fault(clock.now(), type(exc).__name__, str(exc)))
            raise RunEnded(self.state, reason) from None
        except BaseException as exc:  # Ctrl-C outside our handlers: stop first, then go on
            self._interrupted(index, step.name, exc)
            raise
        results = outcome.as_dict()
        self.outcomes[index] = outcome
        self.results[index] = results
        self.bus.publish(StepFinished(clock.now(), index, step.name, "completed", results))
        return outcome

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
            reason = f"{type(exc).__name__}: {exc}"
            self._end(index, name, RunState.FAILED, "failed", reason,
                      Fault(self.rig.clock.now(), type(exc).__name__, reason))

    def _end(self, index: int | None, name: str, state: RunState, status: str, reason: str,
             fault: Fault | None = None) -> RunState:
        """The way out of a run that ended short: safe stop first (stop, read back, safe
        position), then the fault, the safe state, the step's end (``index`` None: it ended
        between steps) and the run's."""
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
        if index is not None:
            self.bus.publish(StepFinished(clock.now(), index, name, status, {"reason": reason}))
        self._set_state(state, reason)
        self.bus.publish(Finished(clock.now(), state, reason))
        return state


def _origin(exc: BaseException) -> str:
    """``file:line`` of the innermost frame of ``exc`` outside gelrig's own packages (where a
    script went wrong), or ''."""
    import sysconfig
    import traceback
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    skip = [root / name for name in ("instrument", "drivers", "simulators", "protocols",
                                     "gui", "gelrig")]
    skip.append(Path(sysconfig.get_paths()["stdlib"]).resolve())
    found = ""
    for frame in traceback.extract_tb(exc.__traceback__):
        path = Path(frame.filename).resolve()
        if not ({"site-packages", "dist-packages"} & set(path.parts)
                or any(path.is_relative_to(package) for package in skip)):
            found = f"{path.name}:{frame.lineno}"
    return found
