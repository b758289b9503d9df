"""The scripting API's entry points: open a rig, run protocols and scripts on it, rehearse.

A composition root like the CLI (it builds rigs through the factory); re-exported by the
``gelrig`` package, which lists the whole public surface (``gelrig.__all__``)::

    import gelrig

    with gelrig.open_rig("compression") as rig:      # the built-in simulated rig, virtual time
        result = rig.run("paper:compression", out="runs/paper")
        print(result.state, result.steps[-1]["results"]["fits"][0]["relax"])

Every run goes through the same wiring as ``gelrig run``: the runner (preflight, caps,
interlocks on every sample, pause, abort, watchdog), the recorder (HDF5 streamed and flushed,
run.json), the safe stop on any way out. Leaving the ``with`` block by an error or Ctrl-C
stops all motion and puts the sample in its safe state before the instruments are closed.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import ConfigError, GelrigError, InterlockTripped, Refused
from gelrig.instrument.core.store import RunDirectory, check_out_dir
from gelrig.instrument.core.units import to_si
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import Event, EventBus
from gelrig.protocols.manual_motion import Guarded, approach_speed, guarded, still_loaded
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rehearsal import RehearsalReport
from gelrig.protocols.resolve import make_clock, resolve_procedure, resolve_rig
from gelrig.protocols.rig import CompressionRig, Rig, ShearRig
from gelrig.protocols.rigfile import RigSpec
from gelrig.protocols.safestop import SafeState
from gelrig.protocols.sample import SampleRef

if TYPE_CHECKING:
    from gelrig.interactive import InteractiveRun

log = logging.getLogger(__name__)

#: A quantity a script gives: a unit string (``"0.5 mm/s"``) or an SI number.
Quantity = str | float

#: Wall seconds the safe stop on leaving a session by an error may take.
SAFE_STOP_BUDGET = 15.0


@dataclass
class RunResult:
    """How a run ended and where its data is: ``state`` ("completed", "aborted", "failed"),
    why, the run directory, and run.json's step records (name, kind, status, samples,
    ``results``, ``params``)."""

    state: str
    reason: str
    path: Path
    steps: list[dict[str, Any]] = field(default_factory=list)
    safe_state: dict[str, Any] | None = None
    #: the protocol's (or script's, or interactive run's) name
    name: str = ""

    @property
    def ok(self) -> bool:
        return self.state == "completed"

    def __repr__(self) -> str:
        """One line: state, name, steps, where; why, when it ended short (the step records
        stay in ``steps``)."""
        done = sum(1 for s in self.steps if s.get("status") == "completed")
        count = (f"{len(self.steps)} step{'' if len(self.steps) == 1 else 's'}"
                 if done == len(self.steps) else f"{done} of {len(self.steps)} steps completed")
        why = ""
        if not self.ok and self.reason:
            why = f": {self.reason if len(self.reason) <= 120 else self.reason[:117] + '...'}"
        return f"<RunResult {self.state} {self.name!r} {count}, {self.path}{why}>"

    def results(self, name: str) -> dict[str, Any]:
        """The results of the (last) step called ``name``."""
        for step in reversed(self.steps):
            if step.get("name") == name:
                return dict(step.get("results") or {})
        raise KeyError(f"no step named {name!r} in {self.path}; steps: "
                       f"{', '.join(str(s.get('name')) for s in self.steps)}")


class RigSession:
    """An open rig: its instruments (through their contracts, under the rig file's caps),
    its clock, and runs recorded on it. Use as a context manager (:func:`open_rig`)."""

    def __init__(self, spec: RigSpec, clock: Clock, clock_spec: str):
        from gelrig.factory import build_rig

        self.spec = spec
        self.clock = clock
        self.clock_spec = clock_spec
        self.rig: Rig = build_rig(spec, clock)
        self.control = RunControl()
        self._closed = False
        #: the interactive run open on this rig, if any (one at a time)
        self._interactive: InteractiveRun | None = None

    @property
    def kind(self) -> str:
        """``"compression"`` or ``"shear"``."""
        return self.rig.kind

    def __repr__(self) -> str:
        where = "simulated" if self.spec.simulated else "real instruments"
        state = "closed" if self._closed else (
            f"interactive run open in {self._interactive.dir}" if self._interactive
            else "open")
        return (f"<RigSession {self.kind} rig {self.spec.name!r} ({where}, {self.clock_spec} "
                f"clock), {state}>")

    def _idle(self) -> None:
        """Refuse what would use the rig beside an open interactive run (its steps own it)."""
        if self._closed:
            raise GelrigError(f"the rig session {self.spec.source} is closed")
        if self._interactive is not None:
            raise GelrigError(f"an interactive run is open in {self._interactive.dir}; add "
                              "its steps with run.step(...), or end it first (leave its "
                              "with block, or run.end())")

    # -- runs ------------------------------------------------------------------------------
    def run(self, protocol: Procedure | str | os.PathLike[str], out: str | os.PathLike[str]
            | None = None, *, show: bool = False,
            subscribers: Iterable[Callable[[Event], None]] = (),
            sample: SampleRef | None = None,
            params: Mapping[str, Any] | None = None, operator: str | None = None,
            note: str | None = None, tags: Iterable[str] = ()) -> RunResult:
        """Run a protocol (a :class:`~gelrig.protocols.script.Script`, a protocol file, a script
        file, ``"paper:compression"``) into a new run directory ``out`` (default
        ``runs/<time>-<rig>``) and return how it ended. ``show`` prints the CLI's progress;
        ``subscribers`` get every event of the run (the same stream the CLI and GUI use).
        A run that ends short (abort, trip, fault, the watchdog, a script's error, a run
        stuck in an instrument call or in the script's own code and ended from outside) has
        stopped all motion first; its state ("aborted" or "failed") and reason say so, and
        nothing is raised. Ctrl-C aborts the run: motion is stopped and the end recorded,
        then KeyboardInterrupt is raised (a second Ctrl-C ends a stuck run at once). Bad
        input (a protocol for the other rig kind, an ``out`` that is a file) raises
        ConfigError before anything is made. A step the rig's caps or the run's bounds
        refuse (a speed above ``max_velocity``, an overlap beyond the limit) raises
        :class:`~gelrig.instrument.core.errors.Refused` (a ConfigError; its text is the one
        line) and leaves no run folder when nothing of the run had moved: a protocol file's
        steps are checked before the folder is made, a script's as it sends each; one
        refused after earlier steps moved ends the run ``"refused"``, its data kept.
        ``sample``: the sample on the rig (a :class:`~gelrig.protocols.sample.Sample`, a
        table such as ``{"name": "A3", "diameter": "12 mm"}``, or a sample file), replacing a
        protocol file's ``[sample]``: a step that needs a size (``ramp_hold``'s diameter)
        takes it from there, and one that has none raises ConfigError naming the field
        before anything is made; a plain name (``sample="gel-A1"``, not a .toml file)
        renames the protocol's sample, its sizes kept, and names the run folder
        (``runs/<time>-gel-A1-compression``). ``params``: a script's parameters (a missing or
        unknown one is a ConfigError). ``operator``, ``note``, ``tags``: who ran it and why,
        stored in run.json and listed by :func:`gelrig.runs` (ADR 0370)."""
        from gelrig.protocols.host import (
            create_run,
            default_run_dir,
            discard_run,
            new_folders,
            preflight,
        )
        from gelrig.protocols.runinfo import run_info

        self._idle()
        info = run_info(operator, note, tags, option="")
        procedure = resolve_procedure(protocol, params, sample=sample)
        self._check_kind(procedure)
        path = Path(out) if out is not None else default_run_dir(procedure)
        check_out_dir(path)
        refused = preflight(self.rig, procedure)
        if refused:
            raise Refused(f"{refused[0]}; refused before anything moves", procedure.source)
        made = new_folders(path)
        run = create_run(procedure, self.spec, self.clock_spec, path, info)
        result, problem = self._execute(procedure, run, None, show, subscribers)
        if problem:
            discard_run(run, made)
            raise Refused(f"{problem}; refused before anything moves", procedure.source)
        return result

    def resume(self, run_dir: str | os.PathLike[str], *, show: bool = False,
               subscribers: Iterable[Callable[[Event], None]] = ()) -> RunResult:
        """Continue a run that ended short from its last completed step, on this rig (the
        run's protocol, or its script run again with completed steps replayed; an
        interactive run is a ConfigError: continue it with ``run_interactive(resume=...)``).
        A step the rig refuses before anything of this attempt moved raises
        :class:`~gelrig.instrument.core.errors.Refused`; the run folder stays as it was."""
        from gelrig.protocols.host import preflight, prepare_resume, resumable
        from gelrig.protocols.interactive import refuse_interactive

        self._idle()
        run = RunDirectory(os.fspath(run_dir))
        refuse_interactive(run.read_metadata(), str(run.path))  # run_interactive(resume=)
        if run.read_metadata().get("status") == "completed":
            return _result(run)
        meta, procedure, notes = resumable(run)
        for note in notes:
            log.warning("%s", note)
        self._check_kind(procedure)
        with run.lock():
            done = {i: s.get("results") or {} for i, s in run.completed_steps().items()}
            refused = preflight(self.rig, procedure, done)
            if refused:
                raise Refused(f"{refused[0]}; refused before anything moves", procedure.source)
            completed, _ = prepare_resume(run, meta, self.clock_spec, self.clock)
            result, problem = self._execute(procedure, run, completed, show, subscribers,
                                            lock=False)
        if problem:
            raise Refused(f"{problem}; refused before anything moves", procedure.source)
        return result

    def run_interactive(self, name: str = "interactive", out: str | os.PathLike[str]
                        | None = None, *, sample: SampleRef | None = None, show: bool = True,
                        subscribers: Iterable[Callable[[Event], None]] = (),
                        resume: str | os.PathLike[str] | None = None,
                        operator: str | None = None, note: str | None = None,
                        tags: Iterable[str] = ()) -> InteractiveRun:
        """Open one run that steps are added to as you go, from a REPL or notebook: a
        :class:`~gelrig.interactive.InteractiveRun` (use it as a context manager, or call
        its ``end()``). Each ``run.step(kind, name=..., **params)`` runs at once through the
        same runner as a script's step and appends to the one run directory ``out``
        (default ``runs/<time>-<rig>``); ``sample``, ``subscribers``, ``operator``,
        ``note`` and ``tags`` as for :meth:`run`;
        ``show`` prints each step's progress and ``run.log`` lines. ``resume``: an
        interactive run recorded before (also one that completed, or one a killed kernel
        left), continued after its completed steps, whose results later steps see."""
        from gelrig.interactive import open_interactive, resume_interactive

        self._idle()
        if resume is not None:
            self._interactive = resume_interactive(self, resume, show, subscribers)
        else:
            from gelrig.protocols.runinfo import run_info

            info = run_info(operator, note, tags, option="")
            self._interactive = open_interactive(self, name, out, sample, show, subscribers,
                                                 info)
        return self._interactive

    def resume_interactive(self, run_dir: str | os.PathLike[str], *, show: bool = True,
                           subscribers: Iterable[Callable[[Event], None]] = ()
                           ) -> InteractiveRun:
        """``run_interactive(resume=run_dir)``: an interactive run continued."""
        return self.run_interactive(resume=run_dir, show=show, subscribers=subscribers)

    def _check_kind(self, procedure: Procedure) -> None:
        if procedure.rig != self.kind:
            raise ConfigError("protocol", procedure.source, f"runs on a {procedure.rig} rig; "
                              f"this session has the {self.kind} rig {self.spec.source}")

    def _execute(self, procedure: Procedure, run: RunDirectory,
                 completed: Mapping[int, Mapping[str, Any]] | None, show: bool,
                 subscribers: Iterable[Callable[[Event], None]], lock: bool = True
                 ) -> tuple[RunResult, str]:
        """Host the run; returns how it ended and, for a run refused before any of its steps
        started, the refusal's line ('' otherwise)."""
        from gelrig.protocols.host import RunHost, refused_unmoved
        from gelrig.terminal import run_in_terminal

        bus = EventBus()
        for subscriber in subscribers:
            bus.subscribe(subscriber)
        with RunHost(self.rig, procedure, run, completed=completed, bus=bus,
                     lock=lock) as host:
            try:
                run_in_terminal(host, show=show, exit=lambda code: None, ctrl_c="raise")
            except Exception as exc:  # the run's thread raised after its end: it ended
                log.error("the run's thread ended with %s: %s", type(exc).__name__, exc,
                          exc_info=exc)
                if host.state.finished:
                    return _result(run), ""
                run.update(status="failed", reason=f"{type(exc).__name__}: {exc}")
        return _result(run), refused_unmoved(host)

    # -- manual motions, under the interlocks ------------------------------------------------
    def home(self) -> Guarded:
        """Home the stage (compression rig) and wait until it is done."""
        self._idle()
        rig = self._compression()
        return self._guard("home", rig.home, toward=False)

    def move_plate(self, speed: Quantity, to: Quantity | None = None,
                   by: Quantity | None = None, confirm: bool = False) -> Guarded:
        """Move the plate to ``to`` or ``by`` a distance at ``speed``: unit strings
        (``move_plate("0.5 mm/s", to="3 mm")``, ``by="-0.1 mm"``) or SI numbers (m, m/s); a
        bad value is a :class:`ConfigError` naming the argument. Watched under the rig's
        interlocks like a protocol step (a trip stops it within one sample and raises
        :class:`InterlockTripped`); refused before homing (:class:`NotHomed`). Toward the
        sample before a contact search (first touch unknown: the overlap limit is not armed)
        it is refused (:class:`FirstTouchUnknown`) unless ``confirm``, and then goes at most
        the safe approach speed (:data:`APPROACH_SPEED`)."""
        self._idle()
        rig = self._compression()
        v = quantity(speed, "m/s", "move_plate", "speed")
        target = None if to is None else quantity(to, "m", "move_plate", "to")
        step = None if by is None else quantity(by, "m", "move_plate", "by")
        if (target is None) == (step is None):
            raise ConfigError("move_plate", f"to={to}, by={by}", "give exactly one of to, by")
        v = approach_speed(rig, v, target, step, confirm)
        return self._guard("move the plate", lambda: rig.move_plate(v, target, step),
                           toward=rig.toward(target, step))

    def set_gap(self, gap: Quantity) -> Guarded:
        """Move the rheometer's lift to ``gap`` (``"1 mm"``, or m), watched under the
        interlocks."""
        self._idle()
        rig = self._shear()
        to = quantity(gap, "m", "set_gap", "gap")
        return self._guard("set the gap", lambda: rig.set_gap(to),
                           toward=to < rig.rheometer.gap())

    def readings(self) -> dict[str, float]:
        """Live values at rest (SI): position and force (the mean of the last 0.1 s), or gap,
        angle, torque, normal force. Waits 0.1 s on the session's clock for fresh samples."""
        self.rig.readings()  # starts the idle force readout if it is not running
        self.clock.sleep(0.1)
        return self.rig.readings()

    def _guard(self, what: str, start: Callable[[], object], toward: bool) -> Guarded:
        self.control = RunControl()
        done = guarded(self.rig, what, start, self.control, toward=toward)
        if done.outcome == "tripped":
            raise InterlockTripped(done.reason)
        return done

    def _compression(self) -> CompressionRig:
        if not isinstance(self.rig, CompressionRig):
            raise ConfigError("rig", self.spec.source, "is a shear rig; the plate is on the "
                              "compression rig")
        return self.rig

    def _shear(self) -> ShearRig:
        if not isinstance(self.rig, ShearRig):
            raise ConfigError("rig", self.spec.source, "is a compression rig; the gap is on "
                              "the shear rig")
        return self.rig

    # -- the way out ------------------------------------------------------------------------
    def safe_stop(self, reason: str = "script ended") -> SafeState:
        """Stop every motion, read it back, and put the sample in the rig's safe state
        (retract the plate, lift the arm); returns what was verified. Safe means the stop
        verified and the load read back below the loaded level: with the sample still
        loaded the state is not verified and its line says what is loaded."""
        return still_loaded(self.rig, self.rig.safe_stop(reason, SAFE_STOP_BUDGET),
                            self.readings)

    def close(self) -> None:
        """Stop all motion and release the instruments (and their simulators); an
        interactive run still open is ended first (completed)."""
        if self._closed:
            return
        if self._interactive is not None:
            self._interactive.end()
        self._closed = True
        from gelrig.protocols.host import closing_rig

        with closing_rig(self.rig):
            pass

    def __enter__(self) -> RigSession:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if self._interactive is not None:  # left open: ended as its own block would be
                self._interactive.__exit__(kind, exc, tb)
            if exc is not None:  # an error or Ctrl-C in the with block: stop, make safe
                safe = self.safe_stop(f"leaving the rig session: {type(exc).__name__}")
                log.log(logging.INFO if safe.verified else logging.ERROR, "safe stop: %s",
                        safe.line())
                print(f"gelrig: {safe.line()}", file=sys.stderr)
            else:
                self._unload_if_loaded()
        finally:
            self.close()

    def _unload_if_loaded(self) -> None:
        """Leaving normally with the sample still loaded (a manual move into it): unload it
        to the rig's safe position first, and say so."""
        try:
            self.rig.stop_all()
            why = self.rig.load_state(self.readings())
        except Exception as exc:  # cannot tell: make it safe all the same
            why = f"its state could not be read ({type(exc).__name__}: {exc})"
        if why is None:
            return
        safe = self.rig.unload()
        log.log(logging.INFO if safe.verified else logging.ERROR, "unload on leaving: %s",
                safe.line())
        print(f"gelrig: the sample was loaded ({why}) when the rig session ended: "
              f"{safe.line()}", file=sys.stderr)


def quantity(value: Quantity, unit: str, call: str, arg: str) -> float:
    """``value`` (a unit string or an SI number) in SI ``unit``. A bad value is a one-line
    ConfigError naming ``call``'s argument, the value and what is allowed."""
    example = {"m": "'3 mm'", "m/s": "'0.5 mm/s'"}.get(unit, f"'1 {unit}'")
    allowed = f"a number in {unit}, or a string with a unit like {example}"
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise ConfigError(f"{call} {arg}", value, allowed)
    try:
        return to_si(value, unit, arg)
    except ConfigError:
        raise ConfigError(f"{call} {arg}", value, allowed) from None


def _result(run: RunDirectory) -> RunResult:
    meta = run.read_metadata()
    table = meta.get("protocol")
    head = table.get("protocol") if isinstance(table, dict) else None
    name = head.get("name") if isinstance(head, dict) else None
    return RunResult(str(meta.get("status", "?")), str(meta.get("reason") or ""), run.path,
                     list(meta.get("steps", [])), meta.get("safe_state"),
                     name if isinstance(name, str) else "")


def open_rig(rig: str | os.PathLike[str] | RigSpec = "compression",
             clock: str | Clock | None = None) -> RigSession:
    """Open a rig: ``"compression"`` or ``"shear"`` (the built-in simulated rigs), a rig
    file, or a parsed :class:`RigSpec`; on ``clock`` ``"virtual"`` (default for a simulated
    rig), ``"real"`` (default otherwise), ``"paced:K"``, or a Clock. Use it as a context
    manager: leaving the block stops everything, and by an error or Ctrl-C first puts the
    sample in its safe state."""
    spec = resolve_rig(rig)
    made, text = make_clock(clock, spec)
    return RigSession(spec, made, text)


def rehearse(protocol: Procedure | str | os.PathLike[str],
             rig: str | os.PathLike[str] | RigSpec | None = None, *,
             sample: SampleRef | None = None,
             params: Mapping[str, Any] | None = None) -> RehearsalReport:
    """What ``gelrig plan`` measures: the protocol (or script) run in virtual time on the
    rig's twin (every instrument simulated under the same limits), counted, not recorded;
    ``sample`` and ``params`` as for :meth:`RigSession.run`."""
    from gelrig.factory import build_twin
    from gelrig.protocols.rehearsal import rehearse as rehearse_on

    procedure = resolve_procedure(protocol, params, sample=sample)
    spec = resolve_rig(rig, procedure)
    twin = build_twin(spec)
    try:
        return rehearse_on(twin, procedure)
    finally:
        twin.close()


def analyze(run_dir: str | os.PathLike[str], out: str | os.PathLike[str] | None = None,
            **options: Any) -> Any:
    """``gelrig analyze``: the report and fits of a run directory (see
    :func:`gelrig.analyze_run.analyze_run` for the options)."""
    from gelrig.analyze_run import analyze_run

    return analyze_run(os.fspath(run_dir), None if out is None else os.fspath(out), **options)


def script_main(argv: list[str] | None = None) -> int:
    """``python script.py [options]`` as ``gelrig run script.py [options]``: put
    ``raise SystemExit(gelrig.script_main())`` under ``if __name__ == "__main__":``."""
    from gelrig.cli import main

    args = sys.argv[1:] if argv is None else argv
    return main(["run", os.path.abspath(sys.argv[0]), *args])


def load_protocol(reference: str | os.PathLike[str]) -> Procedure:
    """A protocol file, a script file (``.py``) or ``"paper:compression"`` /
    ``"paper:shear"``, loaded and validated (nothing runs)."""
    return resolve_procedure(reference, check=False)


def register_step(definition: Any) -> Any:
    """Class decorator: make a :class:`StepDefinition` subclass nameable by its ``kind`` from
    scripts (``run.step("my_kind", ...)``) and from protocol files that list its module in
    ``[protocol] step_kinds``."""
    from gelrig.protocols.steps import register

    return register(definition)


def step_kinds() -> dict[str, str]:
    """Every step kind a protocol can name now (built-in and registered): kind -> rig."""
    from gelrig.protocols.steps import KINDS

    return {kind: d.rig_kind for kind, d in KINDS.items()}
