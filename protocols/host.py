"""The run host: one run of a procedure on a built rig, from its run directory to teardown.

Every front end runs a procedure through a :class:`RunHost`: ``gelrig run`` / ``resume`` /
``demo``, the scripting API, the GUI and a campaign member. The host owns the run's life:

- the run directory (one creation path, :func:`create_run`, with its checks and the script's
  copy; :func:`resumable` and :func:`prepare_resume` for a resume) and its lock;
- the run's log (``RUN_DIR/gelrig.log``, tracebacks included);
- the runs root's catalog (``ROOT/.gelrig-runs.sqlite``, ADR 0370), told as the run starts
  and ends, never waited for;
- the wiring: the Recorder as a critical subscriber of the event bus, the instruments'
  identities and the status in run.json, the Runner (preflight, caps, interlocks, watchdog,
  the safe stop on any way out);
- the thread the steps run on (:meth:`RunHost.start`) or the caller's (:meth:`RunHost.run`);
- pause / resume / abort / end-hold;
- a run stuck in an instrument call: :meth:`RunHost.stuck` tells when an abort was not
  honoured in time, and :meth:`RunHost.end_from_outside` runs the rig's safe stop from
  another thread (every call bounded) and records the end in run.json: the same record
  whichever front end ran it;
- teardown (the recorder unsubscribed, the log detached, the lock released); the rig's
  owner closes the rig (:func:`closing_rig`): a session or the GUI keeps it across runs.

Front ends keep only their faces: the CLI its Ctrl-C mapping and console view, the GUI its
widgets, the API its return value.
"""

from __future__ import annotations

import contextlib
import logging
import re
import shutil
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gelrig.instrument.core.catalog import CATALOG_NAME, OPEN_STATUSES, index_run
from gelrig.instrument.core.clock import Clock, skip_to
from gelrig.instrument.core.errors import ConfigError, GelrigError
from gelrig.instrument.core.memory import release_freed_memory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, RunState
from gelrig.protocols.origin import stuck_site
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rig import Rig
from gelrig.protocols.rigfile import RigSpec
from gelrig.protocols.runinfo import RunInfo
from gelrig.protocols.runner import Runner
from gelrig.protocols.safestop import AxisState, SafeState, bounded

if TYPE_CHECKING:  # the HDF5 store (h5py) is loaded when a run is made, not by a plan
    from gelrig.instrument.core.store import RunDirectory

log = logging.getLogger(__name__)

#: Wall seconds an aborted run has to begin its own safe stop before it counts as stuck.
GRACE = 3.0
#: Wall-time budget of the safe stop run from outside a stuck run (retract included).
EMERGENCY_BUDGET = 12.0
#: Wall seconds the rig's close may take at the end of a run.
CLOSE_TIMEOUT = 10.0
#: Name of the run's log file in its directory.
LOG_NAME = "gelrig.log"
#: What a stuck run's reason gets appended.
STUCK = " (the run was stuck in an instrument call)"
#: While the process lives, a safe stop that was not confirmed is tried again this often
#: (wall s, from the end of one attempt to the next) ...
PENDING_PERIOD = 1.0
#: ... for at most this long (wall s): a link that comes back meanwhile gets its stop, its
#: read-back and the safe action (run.json ``safe_state.completed_later``).
PENDING_LIMIT = 60.0


# ---- the run directory ---------------------------------------------------------------------
def software() -> dict[str, str]:
    """What made the run: gelrig's version and Python's."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("gelrig")
    except PackageNotFoundError:  # a source tree that is not installed
        found = "0+unknown"
    return {"name": "gelrig", "version": found, "python": sys.version.split()[0]}


def run_metadata(procedure: Procedure, rig: RigSpec, clock_spec: str,
                 info: RunInfo | None = None) -> dict[str, Any]:
    """run.json's head: software, the procedure's table, the sample it measures, who ran it
    and why (operator, note, tags), the rig's table, the clock."""
    sample = procedure.sample
    return {
        "software": software(),
        "sample": None if sample is None else sample.table(),
        **(info or RunInfo()).table(),
        "protocol": dict(procedure.table), "protocol_file": procedure.source,
        "rig": rig.table, "rig_file": rig.source, "clock": clock_spec,
        "started_wall": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def default_run_dir(procedure: Procedure, root: Path = Path("runs")) -> Path:
    """``ROOT/<YYYYmmdd-HHMMSS>-<sample>-<rig kind>`` (``-<sample>`` when the sample has a
    name), or ``...-2``, ``-3`` if a run is there."""
    slug = _slug(procedure.rig)
    sample = procedure.sample
    if sample is not None and _slug(sample.name):
        slug = f"{_slug(sample.name)[:60]}-{slug}"
    return unique_dir(root / f"{time.strftime('%Y%m%d-%H%M%S')}-{slug}")


def _slug(text: str) -> str:
    """``text`` as part of a folder name: letters, digits, ``.``, ``_``; runs of anything
    else as one ``-``."""
    out = "".join(c if c.isalnum() or c in "._" else "-" for c in text.strip())
    return re.sub(r"-{2,}", "-", out).strip("-.")


def unique_dir(path: Path) -> Path:
    """``path``, or ``path-2``, ``path-3``... if a run is already there."""
    candidate, k = path, 2
    while (candidate / "run.json").exists():
        candidate = path.with_name(f"{path.name}-{k}")
        k += 1
    return candidate


def create_run(procedure: Procedure, rig: RigSpec, clock_spec: str, out: Path,
               info: RunInfo | None = None) -> RunDirectory:
    """The one way a run directory is made: ``out`` checked (a file, or a folder holding
    something else, is a ConfigError naming ``--out``), run.json's metadata written (``info``:
    operator, note, tags), and for a script run a copy of the script beside the data (what
    made it; what a resume falls back on when the file is gone)."""
    from gelrig.instrument.core.store import RunDirectory, check_out_dir
    from gelrig.protocols.script import COPY_DIR, Script

    check_out_dir(out)
    run = RunDirectory.create(out, run_metadata(procedure, rig, clock_spec, info))
    if isinstance(procedure, Script) and procedure.path and Path(procedure.path).is_file():
        folder = run.path / COPY_DIR
        folder.mkdir(exist_ok=True)
        shutil.copyfile(procedure.path, folder / Path(procedure.path).name)
    return run


def new_folders(out: Path) -> list[Path]:
    """The folders :func:`create_run` will make for ``out``: ``out`` and each missing parent,
    innermost first (what :func:`discard_run` may take away again)."""
    made = []
    for folder in (out, *out.parents):
        if folder.exists():
            break
        made.append(folder)
    return made


def refused_unmoved(host: RunHost) -> str:
    """The refusal's line (``step 0 (probe): speed ... above ...``) of a run refused before
    any of its steps started, so before anything moved; '' for any other end."""
    runner = host.runner
    if host.outside_end is None and runner.state is RunState.REFUSED and not runner.started:
        return runner.refusal
    return ""


def discard_run(run: RunDirectory, made: list[Path]) -> None:
    """Take away the run folder of a new run refused before anything moved: only what
    :func:`create_run` and the host made (run.json, reserve, lock, log, the script's copy),
    never a step file (:meth:`RunDirectory.discard_empty` keeps a folder that holds one),
    then the parents made for it if they are empty (the run index the host started in a
    root made for the run goes with it; in a root that was there the index drops the
    entry when it is next read). A folder that was there before, empty,
    is left empty."""
    from gelrig.protocols.script import COPY_DIR

    copy = run.path / COPY_DIR
    if copy.is_dir() and not copy.is_symlink():
        for entry in copy.iterdir():
            entry.unlink()
        copy.rmdir()
    run.discard_empty(also=(LOG_NAME,))
    if run.path not in made:
        run.path.mkdir(exist_ok=True)
    for folder in made[1:]:  # innermost first; one holding anything else stays
        with contextlib.suppress(OSError):
            if folder == run.path.parent:  # the catalog the run made in a root made for it
                for name in (CATALOG_NAME, f"{CATALOG_NAME}-journal"):
                    (folder / name).unlink(missing_ok=True)
            folder.rmdir()


def resumable(run: RunDirectory) -> tuple[dict[str, Any], Procedure, list[str]]:
    """What a resume of ``run`` needs from its run.json: the metadata, the procedure to run
    again (its protocol table, or the script it names) and notes for people."""
    from gelrig.protocols.script import procedure_from_table

    meta = run.read_metadata()
    for key in ("protocol", "rig"):
        if not isinstance(meta.get(key), dict):
            raise ConfigError(key, meta.get(key, "missing"), "run.json must hold the "
                              f"{key} table to resume", str(run.meta_path))
    procedure, notes = procedure_from_table(meta["protocol"],
                                            str(meta.get("protocol_file", "<run.json>")),
                                            run.path)
    return meta, procedure, notes


def prepare_resume(run: RunDirectory, meta: Mapping[str, Any], clock_spec: str,
                   clock: Clock | None = None) -> tuple[dict[int, Mapping[str, Any]], list[str]]:
    """Before a resume (the run locked): keep the partial data of unfinished steps under new
    names, reserve space, record the resume, and move a virtual or paced ``clock`` on to the
    run's last recorded lab time (one time base per run: the analysis joins the steps'
    motions); returns the completed steps' results by index and the archived files."""
    archived = run.archive_incomplete()
    completed = {i: s.get("results") or {} for i, s in run.completed_steps().items()}
    run.reserve_space()
    run.update(resumed=[*meta.get("resumed", []), clock_spec], storage_fault=None)
    if clock is not None:
        skip_to(clock, last_lab_time(run.read_metadata()))
    return completed, archived


def last_lab_time(meta: Mapping[str, Any]) -> float:
    """The latest lab time (s) run.json records of any step or attempt (0 if none)."""
    times = [float(step[key]) for group in ("steps", "interrupted_steps")
             for step in meta.get(group, []) for key in ("started", "finished")
             if isinstance(step.get(key), int | float)]
    return max(times, default=0.0)


def preflight(rig: Rig, procedure: Procedure,
              completed: Mapping[int, Mapping[str, Any]] | None = None) -> list[str]:
    """Why ``rig``'s caps refuse a step of ``procedure`` known up front (the runner's own
    check, :meth:`Runner.preflight`), before any run directory exists: one line per problem,
    naming the step (``step 0 (probe): speed 1.31 mm/s above ...``); [] when none. A front
    end calls it on the built rig before :func:`create_run`, so a refused protocol leaves no
    run folder and nothing moves; the run itself checks again."""
    return Runner(rig, procedure, completed=completed).preflight()


@contextlib.contextmanager
def _ctrl_c_flag() -> Iterator[Callable[[], bool]]:
    """While it lasts, Ctrl-C only sets a flag (on the main thread; elsewhere it stays a
    KeyboardInterrupt): a press during a safe stop attempt, whose errors the safe stop
    swallows (KeyboardInterrupt included), is not lost (the chaos soak's finding: a Ctrl-C
    there left the retries running their full 60 s)."""
    pressed = [False]
    if threading.current_thread() is not threading.main_thread():
        yield lambda: pressed[0]
        return

    def press(signum: int, frame: object) -> None:
        pressed[0] = True

    previous = signal.signal(signal.SIGINT, press)
    try:
        yield lambda: pressed[0]
    finally:
        signal.signal(signal.SIGINT, previous)


class RunLogHandler(logging.FileHandler):
    """The run's log file. A write that fails (disk full, I/O error) ends the log quietly:
    the run reports the storage fault in its own line, and the terminal gets no "Logging
    error" traceback per record (the chaos soak's disk_full finding)."""

    failed = False

    def emit(self, record: logging.LogRecord) -> None:
        if not self.failed:
            super().emit(record)

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 (logging's name)
        if isinstance(sys.exc_info()[1], OSError):
            self.failed = True
            return
        super().handleError(record)

    def close(self) -> None:
        try:
            super().close()
        except OSError:  # the last flush on a full disk; the file is closed all the same
            self.failed = True


@contextlib.contextmanager
def run_logging(path: Path) -> Iterator[Path]:
    """Send the log of a run, tracebacks included, to ``path`` while the run lasts; so do
    uncaught exceptions of its threads."""
    root = logging.getLogger()
    handler = RunLogHandler(path, encoding="utf-8", delay=False)
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


@contextlib.contextmanager
def closing_rig(rig: Rig) -> Iterator[Rig]:
    """Close ``rig`` on the way out (motion stopped first, bounded: a frozen instrument
    cannot keep the process)."""
    try:
        yield rig
    finally:
        try:
            bounded(rig.close, CLOSE_TIMEOUT, "closing the rig")
        except Exception as exc:
            log.error("closing the rig: %s", exc, exc_info=True)


# ---- the host ------------------------------------------------------------------------------
class RunHost:
    """One run of ``procedure`` on the built ``rig`` into ``run``; use as a context manager.

    The constructor checks that the procedure runs on this rig (GelrigError, nothing
    written); entering locks the run directory, starts its log and wires the recorder;
    leaving undoes that. The rig stays open: its owner closes it (:func:`closing_rig`).
    ``completed`` holds the results of the steps a resumed run skips; ``watched`` False when
    nobody watches the run (a campaign: no live refits of a fixed hold); ``lock`` False when
    the caller holds the run directory's lock already (a resume prepares under it).
    """

    def __init__(self, rig: Rig, procedure: Procedure, run: RunDirectory, *,
                 completed: Mapping[int, Mapping[str, Any]] | None = None,
                 bus: EventBus | None = None, control: RunControl | None = None,
                 watched: bool = True, lock: bool = True):
        self.rig = rig
        self.procedure = procedure
        self.directory = run
        self.bus = EventBus() if bus is None else bus
        self.control = RunControl() if control is None else control
        self.runner = Runner(rig, procedure, self.bus, self.control, completed, watched)
        self.log_path = run.path / LOG_NAME
        self._lock = lock
        self._stack = contextlib.ExitStack()
        self._entered = False
        self._index_warned = False
        self._thread: threading.Thread | None = None
        self._worker: threading.Thread | None = None  # the thread the steps run on
        self._outcome: list[RunState | BaseException] = []
        self._returned = False  # the runner has returned (on whichever thread ran it)
        self._outside: threading.Thread | None = None
        #: what the safe stop from outside verified, once it has ended (see end_from_outside)
        self.outside_end: SafeState | None = None
        #: the status run.json records for an end from outside ("failed" or "aborted")
        self.outside_status = ""
        #: a Ctrl-C gave up the retries of a safe stop not confirmed (complete_pending)
        self.pending_given_up = False

    # -- life ----------------------------------------------------------------------------
    def __enter__(self) -> RunHost:
        stack = self._stack
        try:
            if self._lock:
                stack.enter_context(self.directory.lock())
            stack.enter_context(run_logging(self.log_path))
            from gelrig.protocols.recorder import Recorder  # with the HDF5 store: a run only

            stack.callback(self.bus.subscribe(Recorder(self.directory), critical=True))
            # indexed first: once run.json says "running" the front end takes over at once
            # (its Ctrl-C handling among the first things)
            self._index(status="running")
            self.directory.update(instruments=self.rig.identities, status="running",
                                  finished_wall="")
            # what a resumed script must ask for again at each completed step
            self.runner.recorded = {i: (str(s.get("name")), str(s.get("kind")))
                                    for i, s in self.directory.completed_steps().items()}
        except BaseException:
            self._teardown()
            raise
        self._entered = True
        return self

    def __exit__(self, *exc: object) -> None:
        self._teardown()

    def _teardown(self) -> None:
        try:
            try:
                if self._entered:
                    self._record_end()
            finally:
                self._stack.close()
        finally:  # what the run freed goes back to the system (a process runs many)
            release_freed_memory()

    def _record_end(self) -> None:
        """run.json's ``finished_wall`` once the run has ended, and the catalog told."""
        try:
            status = self.directory.read_metadata().get("status")
            if status not in OPEN_STATUSES:
                self.directory.update(finished_wall=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        except Exception as exc:  # the record of a run must not fail on its end time
            log.warning("could not record the wall end time: %s: %s", type(exc).__name__, exc)
        self._index()

    def _index(self, status: str | None = None) -> None:
        """Tell the runs root's catalog (ADR 0370) without waiting (``status``: the one
        run.json is about to say): a locked or damaged index is one warning line (once per
        run) and the run goes on."""
        problem = index_run(self.directory.path, status)
        if not problem:
            return
        log.warning("%s", problem)
        if not self._index_warned:
            self._index_warned = True
            print(f"gelrig: warning: {problem}", file=sys.stderr, flush=True)

    def run(self) -> RunState:
        """Run every step not yet completed on the calling thread; returns the final state
        (a procedure's BaseException, e.g. Ctrl-C, propagates after the safe stop)."""
        if not self._entered:
            raise GelrigError("a run host runs inside its with block")
        self._worker = threading.current_thread()
        self.rig.end_monitoring()  # the run starts its own acquisition
        try:
            return self.runner.run()
        finally:
            try:
                self._record_time_base()
            finally:
                self._returned = True  # the instruments are free again (see pending)

    def _record_time_base(self) -> None:
        """run.json's ``time_base``: each instrument's time mapping and its uncertainty as
        the run ended (ADR 0241); a rig that cannot say leaves it out."""
        time_base = getattr(self.rig, "time_base", None)
        if time_base is None:
            return
        try:
            self.directory.update(time_base=time_base())
        except Exception as exc:  # the record of a run must not fail on its description
            log.warning("could not record the time base: %s: %s", type(exc).__name__, exc)

    def start(self) -> None:
        """Run on a worker thread of the host's own; see :meth:`wait` and :meth:`outcome`."""
        def work() -> None:
            try:
                self._outcome.append(self.run())
            except BaseException as exc:  # handed to whoever asks for the outcome
                self._outcome.append(exc)

        self._thread = threading.Thread(target=work, name="run", daemon=True)
        self._thread.start()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the worker thread up to ``timeout`` s; True once the run has ended (by
        itself, or from outside)."""
        if self._thread is not None:
            self._thread.join(timeout)
        return self.ended

    @property
    def ended(self) -> bool:
        return bool(self._outcome) or self.outside_end is not None

    def outcome(self) -> RunState:
        """The final state: that of the end from outside once there was one (the run's
        thread may come back later: it ended all the same), else the run's own; re-raises
        what the worker thread raised."""
        if self._outcome and isinstance(self._outcome[0], BaseException):
            raise self._outcome[0]
        if self.outside_end is not None:
            return RunState(self.outside_status)
        if self._outcome:
            return self._outcome[0]  # type: ignore[return-value]
        raise GelrigError(f"the run did not end: {self.control.abort_reason}")

    @property
    def state(self) -> RunState:
        if self.outside_end is not None:
            return RunState(self.outside_status)
        return self.runner.state

    @property
    def reason(self) -> str:
        """Why the run ended ('all steps completed', the abort or fault message)."""
        if self.outside_end is not None:
            return self.outside_end.reason
        return self.runner.reason

    # -- control -------------------------------------------------------------------------
    def pause(self) -> None:
        self.control.pause()

    def resume(self) -> None:
        self.control.resume()

    def abort(self, reason: str = "abort requested") -> None:
        self.control.abort(reason)

    def end_hold(self) -> bool:
        """End the hold in progress now (its data kept, the run goes on); False if none."""
        return self.control.end_hold()

    @property
    def holding(self) -> bool:
        return self.control.holding

    # -- a run that does not answer its abort ---------------------------------------------
    def stuck(self, urged: bool = False) -> bool:
        """True when an abort was asked for and the run has not begun its way out within
        :data:`GRACE` s (``urged``, e.g. a third Ctrl-C: at once), or its own safe stop has
        overrun its budget."""
        control = self.control
        if control.abort_time is None or self.ended:
            return False
        waited = time.monotonic() - control.abort_time
        if self.runner.ending:
            return waited > GRACE + EMERGENCY_BUDGET + 5.0
        return urged or waited > GRACE

    def end_from_outside(self, wait: bool = True) -> SafeState | None:
        """The run thread is stuck in an instrument call: run the rig's safe stop from a
        thread of its own (bounded), record the end in run.json (status "failed" with the
        fault when a fault such as the watchdog caused the abort, else "aborted"; the reason;
        the safe state) and return what the safe stop verified. With ``wait`` False it
        returns at once (None until done: poll :attr:`outside_end`). Idempotent."""
        if self._outside is None:
            self._outside = threading.Thread(target=self._end_outside,
                                             name="gelrig-emergency-stop", daemon=True)
            self._outside.start()
        if wait:
            self._outside.join(EMERGENCY_BUDGET + 5.0)
        return self.outside_end

    def _end_outside(self) -> None:
        control, rig = self.control, self.rig
        # should the run's thread come back, it starts no step and reports no completion
        self.runner.ending = True
        worker = self._worker
        frame = sys._current_frames().get(worker.ident or -1) if worker else None
        if frame is not None:
            log.error("the run thread is stuck here:\n%s",
                      "".join(traceback.format_stack(frame)))
        failed = bool(control.fault_kind)
        status = "failed" if failed else "aborted"
        reason = control.abort_reason or "abort requested"
        kind, where = stuck_site(frame)
        if kind == "script" and f"the script's own code ({where})" not in reason:
            reason += f" (the script's own code ({where}) had not returned)"
        elif kind != "script" and "stuck in an instrument call" not in reason:
            reason += STUCK
        log.error("run %s: %s; safe stop from outside the run", status, reason)
        try:
            stuck_in = rig.fence.busy  # the instrument the run thread is stuck in: left alone
            safe = bounded(lambda: rig.safe_stop(reason, EMERGENCY_BUDGET, faulted=stuck_in),
                           EMERGENCY_BUDGET + 2.0, "safe stop")
        except Exception as exc:
            log.error("safe stop did not finish: %s", exc)
            safe = SafeState(reason, [AxisState(name, "", stop_sent=True, errors=[str(exc)])
                                      for name in rig.identities])
        log.log(logging.INFO if safe.verified else logging.ERROR, "safe stop: %s",
                safe.line())
        try:
            meta = self.directory.read_metadata()
            if failed:
                meta.setdefault("faults", []).append({"t": rig.clock.now(),
                                                      "kind": control.fault_kind,
                                                      "message": control.abort_reason})
            meta.update(status=status, reason=reason, safe_state=safe.as_dict())
            self.directory.write_metadata(meta)
        except Exception as exc:
            log.error("could not record the end in run.json: %s", exc, exc_info=True)
        for handler in logging.getLogger().handlers:
            handler.flush()
        self.outside_status = status
        self.outside_end = safe

    @property
    def pending(self) -> SafeState | None:
        """The run's safe stop if it was not verified and the run thread has ended (so the
        instruments are free to try it again), else None."""
        if self.outside_end is not None:
            return None  # the run thread may still be in an instrument call: leave them
        safe = self.runner.safe_state if self._returned else None
        return safe if safe is not None and not safe.verified else None

    def complete_pending(self, period: float = PENDING_PERIOD, limit: float = PENDING_LIMIT
                         ) -> SafeState | None:
        """A safe stop not confirmed (a frozen, delayed or lost link) is tried again every
        ``period`` s for at most ``limit`` s: the stop, its read-back and the safe action. The
        first verified one is recorded in run.json (``safe_state.completed_later``), logged,
        and returned; None if none was (or nothing was pending). Ctrl-C gives up."""
        first = self.pending
        if first is None:
            return None
        start = time.monotonic()
        attempts = 0
        with _ctrl_c_flag() as pressed:
            try:
                while time.monotonic() - start < limit and not pressed():
                    end = time.monotonic() + period
                    while time.monotonic() < end and not pressed():
                        time.sleep(min(0.05, max(0.0, end - time.monotonic())))
                    if pressed():
                        break
                    attempts += 1
                    left = limit - (time.monotonic() - start)
                    safe = self.rig.safe_stop(first.reason,
                                              max(1.0, min(EMERGENCY_BUDGET, left)))
                    if safe.verified:
                        self._record_later(safe, time.monotonic() - start, attempts)
                        return safe
            except KeyboardInterrupt:  # off the main thread no handler is ours
                pass
            else:
                if not pressed():
                    log.error("the pending safe stop was not confirmed within %g s (%d "
                              "attempts)", limit, attempts)
                    return None
        log.error("the pending safe stop was given up by Ctrl-C after %d attempts", attempts)
        self.pending_given_up = True
        return None

    def _record_later(self, safe: SafeState, after: float, attempts: int) -> None:
        log.warning("safe stop completed later (%.1f s after the run ended, attempt %d): %s",
                    after, attempts, safe.line())
        try:
            meta = self.directory.read_metadata()
            before = meta.get("safe_state")
            record: dict[str, Any] = dict(before) if isinstance(before, dict) else {}
            record["completed_later"] = {**safe.as_dict(), "after_s": round(after, 3),
                                         "attempts": attempts}
            meta["safe_state"] = record
            self.directory.write_metadata(meta)
        except Exception as exc:
            log.error("could not record the later safe stop in run.json: %s", exc,
                      exc_info=True)

    def outside_line(self) -> str:
        """The one terminal line of an end from outside: what happened, what was verified,
        where the details are."""
        safe = self.outside_end
        if safe is None:
            return ""
        head = "FAULT" if self.outside_status == "failed" else "ABORTED"
        return f"{head}: {safe.reason}; {safe.line()}; details: {self.log_path}"
