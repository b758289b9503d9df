"""One run from the command line: build the rig, record, show progress, handle Ctrl-C.

Used by ``gelrig run``, ``gelrig resume`` and ``gelrig demo``. Ctrl-C pauses at the next
checkpoint (Enter resumes); a second Ctrl-C aborts, which stops all motion at once; if the run
is stuck in an instrument call, the process ends within seconds all the same (exit code 3),
after a safe stop of its own. The data of every step streams to the run directory while it is
acquired; the log, tracebacks included, to RUN_DIR/gelrig.log, and the terminal gets one line
per fault.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from gelrig import __version__
from gelrig.factory import build_rig
from instrument.clock import Clock, RealClock
from instrument.errors import ConfigError, GelrigError
from instrument.store import RunDirectory
from protocols.control import RunControl
from protocols.events import EventBus, RunState
from protocols.procedure import Procedure
from protocols.rig import Rig
from protocols.rigfile import RigSpec
from protocols.runner import Runner
from protocols.safestop import AxisState, SafeState, bounded
from protocols.session import RecordedRun

if TYPE_CHECKING:
    from gelrig.console import ConsoleView

log = logging.getLogger(__name__)


def check_clock(rig: RigSpec, clock: Clock, spec: str) -> None:
    """A virtual or paced clock only makes sense when every instrument is simulated."""
    if not isinstance(clock, RealClock) and not rig.simulated:
        raise ConfigError("--clock", spec, f"rig {rig.source} has real instruments; "
                          "use --clock real (virtual and paced time need a simulated rig)")


def make_clock(clock: str | Clock | None, rig: RigSpec) -> tuple[Clock, str]:
    """The clock of a run on ``rig`` and how run.json names it: ``clock`` as ``real``,
    ``virtual`` or ``paced:K`` (default: virtual on a simulated rig, real otherwise), or a
    Clock; checked against the rig (:func:`check_clock`; errors name ``--clock``)."""
    from instrument.clock import clock_from_spec

    if clock is None:
        clock = "virtual" if rig.simulated else "real"
    if isinstance(clock, str):
        try:
            made, text = clock_from_spec(clock), clock
        except ConfigError as exc:
            raise ConfigError("--clock", exc.value, exc.allowed) from None
    else:
        made, text = clock, type(clock).__name__.removesuffix("Clock").lower()
    check_clock(rig, made, text)
    return made, text


def new_run(protocol: Procedure, rig: RigSpec, clock_spec: str, out: Path) -> RunDirectory:
    """A new run directory for ``protocol`` on ``rig``: run.json's metadata, and a copy of
    the script beside the data for a script run."""
    from instrument.store import check_out_dir

    check_out_dir(out)
    run = RunDirectory.create(out, metadata(protocol, rig, clock_spec))
    keep_script(protocol, run)
    return run


def resumable(run: RunDirectory) -> tuple[dict[str, Any], Procedure, list[str]]:
    """What a resume of ``run`` needs from its run.json: the metadata, the procedure to run
    again (its protocol table, or the script it names) and notes for people."""
    from protocols.script import procedure_from_table

    meta = run.read_metadata()
    for key in ("protocol", "rig"):
        if not isinstance(meta.get(key), dict):
            raise ConfigError(key, meta.get(key, "missing"), "run.json must hold the "
                              f"{key} table to resume", str(run.meta_path))
    procedure, notes = procedure_from_table(meta["protocol"],
                                            str(meta.get("protocol_file", "<run.json>")),
                                            run.path)
    return meta, procedure, notes


def prepare_resume(run: RunDirectory, meta: Mapping[str, Any], clock_spec: str
                   ) -> tuple[dict[int, Mapping[str, Any]], list[str]]:
    """Before a resume (the run locked): keep the partial data of unfinished steps under new
    names, reserve space, record the resume; returns the completed steps' results by index
    and the archived files."""
    archived = run.archive_incomplete()
    completed = {i: s.get("results") or {} for i, s in run.completed_steps().items()}
    run.reserve_space()
    run.update(resumed=[*meta.get("resumed", []), clock_spec], storage_fault=None)
    return completed, archived


class Interrupts:
    """Ctrl-C presses of a run: the first pauses (Enter resumes), the second aborts; a run
    that does not end within :data:`GRACE` s of the abort is ended by :func:`execute`."""

    def __init__(self, control: RunControl, say: Callable[[str], object]):
        self.control = control
        self.say = say
        self.presses = 0

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.presses += 1
        if self.presses == 1:
            self.control.pause()
            where = ("the hold runs on (pausing would change the physics) and the run pauses "
                     "at the checkpoint after it" if self.control.holding
                     else "the run pauses at the next checkpoint")
            self.say(f"pause requested: {where}; press Enter to resume, Ctrl-C again to "
                     "abort")
            if sys.stdin is not None and sys.stdin.isatty():
                threading.Thread(target=_resume_on_enter, args=(self.control,),
                                 daemon=True).start()
        elif self.presses == 2:
            self.control.abort("aborted by Ctrl-C")
            self.say("aborting: stopping all motion")
        else:
            self.say("ending now")


@contextlib.contextmanager
def interrupt_handling(control: RunControl, say: Any) -> Iterator[Interrupts]:
    """First Ctrl-C pauses (Enter resumes), the second aborts; restored afterwards."""
    interrupts = Interrupts(control, say)
    if threading.current_thread() is not threading.main_thread():
        yield interrupts
        return
    previous = signal.signal(signal.SIGINT, interrupts)
    try:
        yield interrupts
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def run_logging(path: Path) -> Iterator[Path]:
    """Send the log of a run, tracebacks included, to ``path`` (not the terminal) while the
    run lasts; so do uncaught exceptions of its threads."""
    root = logging.getLogger()
    handler = logging.FileHandler(path, encoding="utf-8", delay=False)
    handler.setLevel(logging.DEBUG)
    handler.setFormatter(logging.Formatter(
        "%(asctime)s %(levelname)s %(threadName)s %(name)s: %(message)s"))
    level, hook = root.level, threading.excepthook

    def thread_hook(args: threading.ExceptHookArgs) -> None:
        name = args.thread.name if args.thread else "?"
        logging.getLogger("gelrig").error("thread %s died: %s: %s", name,
                                          args.exc_type.__name__, args.exc_value,
                                          exc_info=args.exc_value)

    root.addHandler(handler)
    root.setLevel(logging.INFO if not logging.NOTSET < level <= logging.INFO else level)
    threading.excepthook = thread_hook
    try:
        yield path
    finally:
        threading.excepthook = hook
        root.removeHandler(handler)
        root.setLevel(level)
        handler.close()


def _resume_on_enter(control: RunControl) -> None:
    with contextlib.suppress(Exception):
        sys.stdin.readline()
        if not control.abort_requested:
            control.resume()


def metadata(protocol: Procedure, rig: RigSpec, clock_spec: str) -> dict[str, Any]:
    return {
        "software": {"name": "gelrig", "version": __version__, "python": sys.version.split()[0]},
        "protocol": dict(protocol.table), "protocol_file": protocol.source,
        "rig": rig.table, "rig_file": rig.source, "clock": clock_spec,
        "started_wall": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


#: Wall seconds an aborted run has to reach its safe stop before the CLI ends it itself.
GRACE = 3.0
#: Wall-time budget of the safe stop the CLI runs itself (retract included).
EMERGENCY_BUDGET = 12.0
#: Wall seconds the rig's close may take at the end of a run.
CLOSE_TIMEOUT = 10.0
#: Name of the run's log file in its directory.
LOG_NAME = "gelrig.log"


def execute(
    protocol: Procedure,
    rig_spec: RigSpec,
    clock: Clock,
    run: RunDirectory,
    completed: Mapping[int, Mapping[str, Any]] | None = None,
    show: bool = True,
    bus: EventBus | None = None,
    control: RunControl | None = None,
    exit: Callable[[int], object] = os._exit,
    rig: Rig | None = None,
) -> tuple[RunState, Runner]:
    """Build the rig, run the protocol into ``run``, close the rig; returns the final state.
    With ``rig`` (already built from ``rig_spec``: a session of the scripting API) that rig
    is used and left open for its owner.

    The log goes to RUN_DIR/gelrig.log. The steps run on a worker thread; if an abort (a
    second Ctrl-C, the watchdog) is not honoured within :data:`GRACE` s because that thread
    is stuck in an instrument call, this thread runs the safe stop itself, records it in
    run.json, prints the one line and calls ``exit`` (3 aborted, 1 failed).
    """
    import gelrig.console  # noqa: F401 - imported before the run shows as "running"

    with run_logging(run.path / LOG_NAME) as log_path:
        owned = rig is None
        used = build_rig(rig_spec, clock) if rig is None else rig
        try:
            recorded = RecordedRun(used, protocol, bus, control, completed).record(run)
            return _execute(recorded, run, show, log_path, exit), recorded.runner
        finally:
            if owned:
                try:
                    bounded(used.close, CLOSE_TIMEOUT, "closing the rig")
                except Exception as exc:
                    log.error("closing the rig: %s", exc, exc_info=True)


def _execute(recorded: RecordedRun, run: RunDirectory, show: bool, log_path: Path,
             exit: Callable[[int], object]) -> RunState:
    from gelrig.console import ConsoleView

    view = ConsoleView(log_path=log_path) if show else None
    say: Callable[[str], object] = view.say if view else (lambda *_: None)
    outcome: list[RunState | BaseException] = []

    def work() -> None:
        try:
            outcome.append(recorded.run())
        except BaseException as exc:  # handed to the calling thread
            outcome.append(exc)

    with contextlib.ExitStack() as stack:
        if view is not None:
            stack.enter_context(view)
            recorded.bus.subscribe(view)
        interrupts = stack.enter_context(interrupt_handling(recorded.control, say))
        worker = threading.Thread(target=work, name="run", daemon=True)
        worker.start()
        while worker.is_alive():
            worker.join(0.1)
            if worker.is_alive() and _stuck(recorded, interrupts):
                _emergency_end(recorded, run, log_path, view, exit, worker)
                worker.join(1.0)  # ``exit`` returned (a test): let the thread be
                break
    if not outcome:
        raise GelrigError(f"the run did not end: {recorded.control.abort_reason}")
    result = outcome[0]
    if isinstance(result, BaseException):
        raise result
    return result


def _stuck(recorded: RecordedRun, interrupts: Interrupts) -> bool:
    """True when an abort was asked for and the run thread has not begun its way out in
    time (a third Ctrl-C: at once), or its own safe stop overran its budget."""
    control = recorded.control
    if control.abort_time is None:
        return False
    waited = time.monotonic() - control.abort_time
    if recorded.runner.ending:
        return waited > GRACE + EMERGENCY_BUDGET + 5.0
    return interrupts.presses >= 3 or waited > GRACE


def _emergency_end(recorded: RecordedRun, run: RunDirectory, log_path: Path,
                   view: ConsoleView | None, exit: Callable[[int], object],
                   worker: threading.Thread) -> None:
    """The run thread is stuck: safe stop from here (on a thread, bounded), record, one line,
    exit (3 aborted, 1 failed by the watchdog)."""
    control = recorded.control
    frame = sys._current_frames().get(worker.ident or -1)
    if frame is not None:
        log.error("the run thread is stuck here:\n%s", "".join(traceback.format_stack(frame)))
    failed = bool(control.fault_kind)
    status = "failed" if failed else "aborted"
    reason = control.abort_reason + " (the run was stuck in an instrument call)"
    log.error("run %s: %s; safe stop from the main thread", status, reason)
    if view is not None:
        view.close()  # from now on this thread tells the end, in one line
    try:
        safe = bounded(lambda: recorded.rig.safe_stop(reason, EMERGENCY_BUDGET),
                       EMERGENCY_BUDGET + 2.0, "safe stop")
    except Exception as exc:
        log.error("safe stop did not finish: %s", exc)
        safe = SafeState(reason, [AxisState(name, "", stop_sent=True, errors=[str(exc)])
                                  for name in recorded.rig.identities])
    log.log(logging.INFO if safe.verified else logging.ERROR, "safe stop: %s", safe.line())
    try:
        meta = run.read_metadata()
        if failed:
            meta.setdefault("faults", []).append({"t": recorded.rig.clock.now(),
                                                  "kind": control.fault_kind,
                                                  "message": control.abort_reason})
        meta.update(status=status, reason=reason, safe_state=safe.as_dict())
        run.write_metadata(meta)
    except Exception as exc:
        log.error("could not record the end in run.json: %s", exc, exc_info=True)
    head = f"{'FAULT' if failed else 'ABORTED'}: {reason}"
    line = f"{head}; {safe.line()}; details: {log_path}"
    print(line, file=sys.stderr, flush=True)
    for handler in logging.getLogger().handlers:
        handler.flush()
    exit(1 if failed else 3)


def keep_script(protocol: Procedure, run: RunDirectory) -> None:
    """A script run keeps a copy of its script beside its data (what made it; what a resume
    falls back on when the file is gone)."""
    import shutil

    from protocols.script import COPY_DIR, Script

    if isinstance(protocol, Script) and protocol.path and Path(protocol.path).is_file():
        folder = run.path / COPY_DIR
        folder.mkdir(exist_ok=True)
        shutil.copyfile(protocol.path, folder / Path(protocol.path).name)


def default_run_dir(protocol: Procedure) -> Path:
    slug = "".join(c if c.isalnum() else "-" for c in protocol.rig)
    return Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{slug}"
