"""Interactive runs: steps added one at a time to one open run, from a REPL or a notebook.

The API's face over an interactive procedure (:mod:`gelrig.protocols.interactive`) hosted by
one :class:`~gelrig.protocols.host.RunHost` for the run's whole life::

    with gelrig.open_rig("compression") as rig:
        run = rig.run_interactive(name="A3 series", sample={"diameter": "12 mm"})
        run.step("compression_contact_search", speed="0.3 mm/s")   # one cell
        run.step("ramp_hold", strain=0.04, hold="600 s")            # a later cell
        run.end()                                                   # or: with ... as run:

Each :meth:`InteractiveRun.step` runs at once on the run's thread through the runner (caps,
interlocks, recorder, checkpoints, the safe stop on any way out) while this thread shows its
progress and maps Ctrl-C, as ``session.run`` does for a whole protocol.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Callable, Iterable
from concurrent.futures import Future, wait
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from gelrig.instrument.core.errors import ConfigError, GelrigError, Refused
from gelrig.instrument.core.fields import Where
from gelrig.instrument.core.store import RunDirectory
from gelrig.instrument.core.units import lab_time
from gelrig.protocols.events import Event, EventBus, Note, RunState
from gelrig.protocols.host import RunHost
from gelrig.protocols.interactive import SOURCE, Interactive
from gelrig.protocols.runner import RunEnded
from gelrig.protocols.spec import make_step
from gelrig.protocols.steps.base import StepDefinition, StepResult

if TYPE_CHECKING:
    from gelrig.api import RigSession, RunResult
    from gelrig.protocols.runinfo import RunInfo

log = logging.getLogger(__name__)


def _no_exit(code: int) -> None:
    """A run stuck after an abort has been ended from outside: the notebook lives on."""


class InteractiveRun:
    """One open run that steps are added to as you go (:meth:`RigSession.run_interactive`):
    ``step`` runs the next step at once and returns its typed result, ``log`` writes a line,
    ``results`` holds every step's result, ``dir`` is the run directory. Leaving its ``with``
    block (or :meth:`end`) ends the run completed; an exception or Ctrl-C in the block
    stops all motion first and ends it failed or aborted."""

    def __init__(self, session: RigSession, procedure: Interactive, run: RunDirectory,
                 stack: contextlib.ExitStack, *,
                 completed: dict[int, Any] | None = None, show: bool = True,
                 subscribers: Iterable[Callable[[Event], None]] = ()):
        self._session = session
        self._procedure = procedure
        self.directory = run
        self.show = show
        self._stack = stack
        bus = EventBus()
        for subscriber in subscribers:
            bus.subscribe(subscriber)
        done = completed or {}
        #: every step's typed result so far, in order (those of a resumed run's earlier
        #: steps too)
        self.results: list[StepResult] = [
            step.definition.Result.from_dict(done[i]) for i, step in
            enumerate(procedure.replay)]
        self._result: RunResult | None = None
        self._host = RunHost(session.rig, procedure, run, completed=completed, bus=bus,
                             lock=False)
        stack.enter_context(self._host)
        self._host.start()

    # -- what it is ----------------------------------------------------------------------
    @property
    def dir(self) -> Path:
        """The run directory (run.json, ``steps/NN_name.h5``, gelrig.log)."""
        return self.directory.path

    @property
    def name(self) -> str:
        return self._procedure.name

    @property
    def open(self) -> bool:
        """Steps can still be added (the run has not ended)."""
        return self._result is None and not self._host.ended

    @property
    def state(self) -> str:
        """"running" while open, then how it ended ("completed", "aborted", "failed")."""
        if self._result is not None:
            return self._result.state
        return self._host.state.value if self._host.ended else RunState.RUNNING.value

    @property
    def result(self) -> RunResult | None:
        """How the run ended (a :class:`RunResult`), None while it is open."""
        return self._result

    def __repr__(self) -> str:
        count = len(self.results)
        return (f"<InteractiveRun {self.state} {self.name!r} {count} step"
                f"{'' if count == 1 else 's'}, {self.dir}>")

    # -- adding steps ----------------------------------------------------------------------
    def step(self, kind: str | StepDefinition[Any, Any, Any] | type, name: str | None = None,
             **params: Any) -> Any:
        """Run the next step now and return its typed result (e.g. a ``RampHoldResult``):
        the same kinds, keys, unit strings and checks as a script's ``run.step``; it sees
        the results of the steps before it (a ``ramp_hold`` takes the last contact search's
        first touch). A bad value or a step the rig's caps refuse raises
        :class:`~gelrig.instrument.core.errors.ConfigError` /
        :class:`~gelrig.instrument.core.errors.Refused` before it moves, and the run stays
        open. A step that ends the run short (a trip, a fault, an abort) stops all motion
        first and raises :class:`~gelrig.protocols.runner.RunEnded`; Ctrl-C aborts the step
        (motion stopped, the run recorded aborted), then raises KeyboardInterrupt."""
        self._check_open()
        index = len(self.results)
        procedure = self._procedure
        built = make_step(kind, name, params, procedure.rig, Where(f"step[{index}]", SOURCE),
                          procedure.sample)
        earlier = tuple(type(r) for r in self.results)
        refused = built.definition.preflight(built.params, self._session.rig, earlier)
        if refused:
            raise Refused(f"step {index} ({built.name}): {refused[0]}; refused before it "
                          "moves (the run stays open)", SOURCE)
        from gelrig.terminal import terminal_face, watch

        host = self._host
        with terminal_face(host, self.show, ctrl_c="raise") as interrupts:
            reply = procedure.feed.submit(built)
            watch(host, lambda timeout: _done(reply, timeout), interrupts, _no_exit)
        if reply.done() and reply.exception() is None and not host.ended:
            result = reply.result()
            self.results.append(result)
            if interrupts.presses:  # pressed as the step completed: the run ends aborted
                raise KeyboardInterrupt
            return result
        self._finish()  # the step ended the run: motion stopped, the end recorded
        if interrupts.presses:
            raise KeyboardInterrupt
        raise RunEnded(self._host.state, self._host.reason)

    def log(self, text: str) -> None:
        """A line in the run's log (RUN_DIR/gelrig.log), shown on the console too when the
        run shows its progress (``show=True``)."""
        text = str(text)
        logging.getLogger("gelrig.script").info("%s", text)
        now = self._session.clock.now()
        self._host.bus.publish(Note(now, text))
        if self.show:
            print(f"[{lab_time(now)}] {text}", file=sys.stderr, flush=True)

    def _check_open(self) -> None:
        if self._result is not None or self._host.ended:
            raise RunEnded(RunState(self.state), f"the interactive run {self.dir} has ended "
                           f"({self.state}); resume it with rig.run_interactive(resume=...)")

    # -- the end -------------------------------------------------------------------------
    def end(self) -> RunResult:
        """End the run as completed (if a step has not ended it already) and return how it
        ended; a sample left loaded is unloaded, as on leaving a rig session. Idempotent."""
        return self._finish(None)

    def __enter__(self) -> InteractiveRun:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if isinstance(exc, RunEnded | GelrigError) and self._host.ended:
            exc = None  # a step ended the run: recorded already
        self._finish(exc)

    def _finish(self, raised: BaseException | None = None) -> RunResult:
        """End the run (completed; or as ``raised`` ends a script: the runner's safe stop
        first), wait for its thread, record, release the run directory."""
        from gelrig.api import _result
        from gelrig.terminal import complete_pending, terminal_face, watch

        if self._result is not None:
            return self._result
        host = self._host
        try:
            if not host.ended:
                if isinstance(raised, Exception):  # its traceback in the user's code, logged
                    log.error("the interactive run's block raised %s: %s",
                              type(raised).__name__, raised, exc_info=raised)
                self._procedure.feed.end(raised)
                with terminal_face(host, self.show, ctrl_c="raise") as interrupts:
                    watch(host, host.wait, interrupts, _no_exit)
            complete_pending(host, self.show)
            try:
                host.outcome()
            except BaseException as exc:  # what the block raised, recorded by the runner
                if isinstance(exc, Exception) and not host.state.finished:
                    self.directory.update(status="failed",
                                          reason=f"{type(exc).__name__}: {exc}")
        finally:
            self._stack.close()  # the host's teardown and the run directory's lock
            self._session._interactive = None
        self._result = _result(self.directory)
        if raised is None and self._result.ok:
            self._session._unload_if_loaded()
        return self._result


def _done(reply: Future[StepResult], timeout: float) -> bool:
    wait([reply], timeout=timeout)
    return reply.done()


def open_interactive(session: RigSession, name: str, out: str | os.PathLike[str] | None,
                     sample: Any, show: bool,
                     subscribers: Iterable[Callable[[Event], None]],
                     info: RunInfo | None = None) -> InteractiveRun:
    """A new interactive run on ``session`` into ``out`` (default ``runs/<time>-<rig>``);
    ``info``: its operator, note and tags."""
    from gelrig.instrument.core.store import check_out_dir
    from gelrig.protocols.host import create_run, default_run_dir
    from gelrig.protocols.sample import resolve_sample

    procedure = Interactive(session.kind, str(name),
                            None if sample is None else resolve_sample(sample))
    path = Path(out) if out is not None else default_run_dir(procedure)
    check_out_dir(path)
    run = create_run(procedure, session.spec, session.clock_spec, path, info)
    stack = contextlib.ExitStack()
    try:
        stack.enter_context(run.lock())
        return InteractiveRun(session, procedure, run, stack, show=show,
                              subscribers=subscribers)
    except BaseException:
        stack.close()
        raise


def resume_interactive(session: RigSession, run_dir: str | os.PathLike[str], show: bool,
                       subscribers: Iterable[Callable[[Event], None]]) -> InteractiveRun:
    """An interactive run recorded before, open again: its completed steps replayed (their
    results come back, nothing moves), new steps added after them."""
    from gelrig.protocols.host import prepare_resume
    from gelrig.protocols.interactive import interactive_from_table, is_interactive

    run = RunDirectory(os.fspath(run_dir))
    meta = run.read_metadata()
    if not is_interactive(meta.get("protocol") or {}):
        raise ConfigError("resume", str(run.path), "is not an interactive run; continue it "
                          "with rig.resume(...) or gelrig resume", str(run.meta_path))
    stack = contextlib.ExitStack()
    try:
        stack.enter_context(run.lock())
        procedure = interactive_from_table(meta["protocol"], str(run.meta_path),
                                           run.completed_steps())
        if procedure.rig != session.kind:
            raise ConfigError("resume", str(run.path), f"was recorded on a {procedure.rig} "
                              f"rig; this session has the {session.kind} rig "
                              f"{session.spec.source}")
        completed, archived = prepare_resume(run, meta, session.clock_spec, session.clock)
        if archived:
            log.info("kept partial data as %s", ", ".join(archived))
        return InteractiveRun(session, procedure, run, stack, completed=dict(completed),
                              show=show, subscribers=subscribers)
    except BaseException:
        stack.close()
        raise
