"""The rig as the GUI drives it: connect, idle readouts, manual commands, one run at a time.

Not a widget: panels call it and listen to its signals. Every instrument call goes through
the single :class:`~gelrig.gui.tasks.RigThread`; a run is hosted by the same
:class:`~gelrig.protocols.host.RunHost` as ``gelrig run`` (its Recorder a critical
subscriber, its log, its end from outside when stuck), so closing the window or a fault never
loses data, and a stuck run ends with the same run.json as on the command line.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from PySide6.QtCore import QObject, Qt, QTimer, Signal

from gelrig.gui.bridge import EventBridge
from gelrig.gui.messages import explain, explain_fault
from gelrig.gui.rundata import RunData
from gelrig.gui.safety import (
    NAMES,
    RUN_SILENT_AFTER,
    SILENT_AFTER,
    SOURCE,
    Safety,
    Silent,
    limits_text,
    source_of,
)
from gelrig.gui.services import Services
from gelrig.gui.tasks import RigThread
from gelrig.instrument.core.clock import Clock, PacedClock, RealClock
from gelrig.instrument.core.errors import GelrigError, InstrumentError, Refused
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import (
    Event,
    EventBus,
    Fault,
    InterlockTrip,
    Progress,
    RunState,
    SafeStopped,
    Samples,
)
from gelrig.protocols.host import (
    EMERGENCY_BUDGET,
    PENDING_LIMIT,
    RunHost,
    create_run,
    default_run_dir,
    discard_run,
    new_folders,
    preflight,
    refused_unmoved,
)
from gelrig.protocols.manual_motion import Guarded, Motion, run_motion, still_loaded, verified_stop
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rig import CompressionRig, Rig
from gelrig.protocols.rigfile import RigSpec
from gelrig.protocols.runinfo import RunInfo
from gelrig.protocols.safestop import SafeState, bounded

log = logging.getLogger(__name__)

#: Force sample rate (Hz) of the idle readout (the USB-6001's lowest; a run restarts the
#: acquisition at its own rate if different).
MONITOR_RATE = 100.0
#: Idle readout period (s, wall time).
MONITOR_PERIOD = 0.2
#: Heartbeat period (ms): how often the GUI thread judges every instrument's silence.
HEARTBEAT_MS = 250


class Readout(dict[str, float]):
    """The idle readout's values, with the instruments that answered and the errors (in
    words) of those that did not."""

    def __init__(self, values: Mapping[str, float], answered: set[str],
                 errors: Mapping[str, str]):
        super().__init__(values)
        self.answered = answered
        self.errors = dict(errors)


def clock_spec(clock: Clock | None, pace: float) -> str:
    """The clock as ``gelrig run --clock`` would name it (stored in run.json)."""
    if isinstance(clock, RealClock):
        return "real"
    return "paced:inf" if math.isinf(pace) else f"paced:{pace:g}"


class RigDesk(QObject):
    """Owns the rig, its clock, the rig thread and the current run."""

    connected = Signal(object)  # Rig
    disconnected = Signal()
    connect_failed = Signal(str)
    readings = Signal(dict)  # column-like name -> SI value, while idle
    readings_failed = Signal(str)
    command_failed = Signal(str, str)  # what, message
    run_started = Signal(object)  # run directory (Path)
    run_finished = Signal(object, str)  # RunState, reason
    run_event = Signal(object)  # run events other than samples and progress
    motion_ended = Signal(object)  # Guarded: how a manual motion ended
    alarm_changed = Signal(str)  # the unacknowledged trip or fault ("" once acknowledged)
    load_changed = Signal(str)  # why the sample counts as loaded ("" when it does not)
    unloaded = Signal(object)  # SafeState of an unload
    stuck = Signal(str)  # the run does not answer its abort: what to do
    emergency_ended = Signal(object)  # SafeState of the safe stop run from outside the run
    safety_changed = Signal(object)  # Safety: the one state every view renders
    stop_verified = Signal(object)  # SafeState of a STOP or a failed command's stop
    pending_done = Signal(object)  # SafeState | None: a retried safe stop completed / given up

    def __init__(self, services: Services, parent: QObject | None = None):
        super().__init__(parent)
        self.services = services
        self.spec: RigSpec | None = None
        self.rig: Rig | None = None
        self.pace = services.pace
        self.worker = RigThread(self)
        self.data = RunData()
        self.control: RunControl | None = None
        self.run_path: Path | None = None
        #: the last run's refusal line when it was refused before anything moved (no folder)
        self.refused = ""
        self.state = RunState.IDLE
        self._bridge: EventBridge | None = None
        self._connecting = False
        self._poll_pending = False
        self._last_poll = time.monotonic()
        self._monitor = QTimer(self)
        self._monitor.setInterval(round(MONITOR_PERIOD * 1000))
        self._monitor.timeout.connect(self._poll)
        #: the unacknowledged interlock trip or fault ("" when none)
        self.alarm = ""
        #: why the sample counts as loaded, from the latest readings ("" when not)
        self.loaded = ""
        #: the latest live values (idle readouts, guarded motions)
        self.values: dict[str, float] = {}
        self._motions: list[RunControl] = []  # manual motions queued or going
        self._live: dict[str, float] = {}  # a guarded motion's newest values (rig thread)
        self._live_lock = threading.Lock()
        self._host: RunHost | None = None
        self._stop_presses = 0
        self._closing = False
        self.wedged = False  # the rig thread is stuck in an instrument call
        self._stuck_said = False
        self._watch = QTimer(self)
        self._watch.setInterval(250)
        self._watch.timeout.connect(self._watch_abort)
        #: instrument key -> when it last answered (monotonic s); values -> when read
        self.heard: dict[str, float] = {}
        self.faults: dict[str, str] = {}  # instrument key -> its last error, in words
        self.read_at: dict[str, float] = {}
        self._run_heard: dict[str, float] = {}  # written by the run's thread, per block
        self._busy: tuple[str, float] | None = None  # a plain command in progress, since
        self._alarm_at = 0.0
        self.safe_line = ""  # the latest verified-stop line, and whether it was verified
        self.safe_verified: bool | None = None
        self._why_off = "no rig connected"
        self._pending: RunHost | None = None  # a run whose safe stop is not confirmed
        self._pending_since = 0.0
        self._pending_busy = False
        self.pending_text = ""
        self._last_safety: Safety | None = None
        self._last_trace = ""  # the readout's last error (rig thread): its traceback once
        self._heartbeat = QTimer(self)
        self._heartbeat.setInterval(HEARTBEAT_MS)
        self._heartbeat.timeout.connect(self._beat)
        self._heartbeat.start()

    # ---- the rig ------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self.control is not None

    @property
    def clock(self) -> Clock | None:
        return self.rig.clock if self.rig is not None else None

    def load_rig(self, path: Path) -> RigSpec:
        """Validate a rig file and make it the one to connect (raises ConfigError)."""
        if self.rig is not None or self._connecting:
            raise GelrigError("disconnect the current rig first")
        self.spec = self.services.load_rig(path)
        return self.spec

    def connect_rig(self) -> None:
        spec = self.spec
        if spec is None or self.rig is not None or self._connecting:
            return
        # a simulated rig's pace scales the waits only (ADR 0240): the GUI's own work and the
        # calls to the twins take their real time, so a pace of 100 neither starves the contact
        # search of plate positions nor stretches a busy moment past a move segment's renewal
        clock: Clock = (PacedClock(self.pace, waits_only=True) if spec.simulated
                        else RealClock())
        self._connecting = True
        self._why_off = "connecting…"
        self._publish()
        self.worker.submit(lambda: self.services.build_rig(spec, clock),
                           done=self._on_connected, failed=self._on_connect_failed)

    def _on_connected(self, rig: Rig) -> None:
        self._connecting = False
        self.rig = rig
        now = time.monotonic()
        self.heard = {key: now for key in rig.identities}
        self.faults, self.read_at, self.values = {}, {}, {}
        self._monitor.start()
        self.connected.emit(rig)
        self._publish()

    def _on_connect_failed(self, exc: BaseException) -> None:
        self._connecting = False
        message = explain(exc)
        self._why_off = "the rig did not connect"
        self._publish()
        log.warning("connecting the rig: %s", message.detail)
        self.connect_failed.emit(message.text)

    def disconnect_rig(self) -> None:
        if self.rig is None or self.running:
            return
        self._monitor.stop()
        self._end_motions("disconnecting")
        rig, self.rig = self.rig, None
        self.values, self.loaded, self.read_at, self.heard, self.faults = {}, "", {}, {}, {}
        self._pending = None  # a later safe stop needs the rig: it is gone (said in the log)
        self._why_off = "disconnected"
        self._publish()  # a trip stays until acknowledged: reconnecting does not clear it
        if self.wedged:  # the rig thread is stuck: nothing can be sent; forget the rig
            self.disconnected.emit()
            return
        self.worker.submit(rig.close, done=lambda _: self.disconnected.emit(),
                           failed=lambda _: self.disconnected.emit())

    def set_pace(self, rate: float) -> None:
        """Pace of simulated time (``math.inf``: as fast as possible); no-op on real time."""
        self.pace = rate
        clock = self.clock
        if isinstance(clock, PacedClock):
            clock.set_rate(rate)

    def clock_spec(self) -> str:
        return clock_spec(self.clock, self.pace)

    # ---- manual control -----------------------------------------------------------------
    def command(self, what: str, fn: Callable[[Rig], object] | Motion) -> bool:
        """Run a manual command on the rig thread; refused during a run. A :class:`Motion`
        is watched under the interlocks until it ends (ADR 0170); any new command first
        ends a motion still going."""
        rig = self.rig
        if rig is None or self.running or self.wedged:
            return False
        self._end_motions(f"superseded by {what}")
        if not isinstance(fn, Motion):
            def plain() -> object:
                self._busy = (what, time.monotonic())
                try:
                    return fn(rig)
                finally:
                    self._busy = None
            return self.worker.submit(plain, failed=lambda exc: self._failed(what, exc))
        control = RunControl()
        self._motions.append(control)
        tripped = bool(self.alarm)

        def task() -> Guarded:
            return run_motion(rig, what, fn, control, self._set_live, tripped)

        def done(result: Guarded) -> None:
            self._motion_over(control)
            self.values = {}  # what the motion saw is not a reading at rest: read again
            if result.safe is not None:
                self._set_safe(result.safe.line(), result.safe.verified)
            if result.outcome == "tripped":
                self._set_alarm(result.reason)
            self.motion_ended.emit(result)
            self._publish()

        def failed(exc: BaseException) -> None:
            self._motion_over(control)
            self.values = {}
            self._failed(what, exc)

        return self.worker.submit(task, done=done, failed=failed)

    def _set_live(self, values: dict[str, float]) -> None:
        """A guarded motion's newest values (rig thread); the readout timer shows them."""
        with self._live_lock:
            self._live.update(values)
        now = time.monotonic()
        for key in values:
            source = SOURCE.get(key)
            if source is not None:
                self._run_heard[source] = now

    def _motion_over(self, control: RunControl) -> None:
        if control in self._motions:
            self._motions.remove(control)

    def _end_motions(self, reason: str) -> None:
        for control in self._motions:
            control.abort(reason)

    @property
    def moving_by_hand(self) -> bool:
        """A manual motion is queued or going."""
        return bool(self._motions)

    def _failed(self, what: str, exc: BaseException) -> None:
        """A command failed: one line in words; the wire detail (and any traceback) goes to
        the log file. An instrument's error stops every axis, verified (said when done):
        a refusal (nothing was sent) needs no stop."""
        message = explain(exc)
        log.warning("%s failed: %s", what, message.detail)
        log.debug("%s failed", what, exc_info=exc)  # the traceback: the log file only
        source = source_of(str(exc))
        if source is not None:
            self.faults[source] = message.text
        refused = isinstance(exc, GelrigError) and not isinstance(exc, InstrumentError)
        self.command_failed.emit(what, message.text if refused else
                                 f"{message.text}. Stopping all motion (verified next)…")
        if not refused and self.rig is not None and not self.wedged:
            self._stop_verified(f"{what} failed")
        self._publish()

    def _stop_verified(self, reason: str) -> None:
        """Stop every axis now (the queue jumped) and read back that it stopped; the line
        goes to :attr:`safe_line` and :attr:`stop_verified`."""
        rig = self.rig
        if rig is None:
            return

        def said(safe: SafeState) -> None:
            self._set_safe(safe.line(), safe.verified)
            self.stop_verified.emit(safe)
            self._publish()

        self.worker.submit(lambda: verified_stop(rig, reason), done=said,
                           failed=lambda exc: log.error("verified stop: %s", exc), urgent=True)

    def _set_safe(self, line: str, verified: bool | None) -> None:
        self.safe_line, self.safe_verified = line, verified

    def stop(self) -> None:
        """Stop all motion now: abort the run if one is going (pressed again while the run
        does not answer: the emergency end), else end a manual motion (the motion's own
        watch stops it within one sample and reads the stop back) or stop every axis,
        verified."""
        if self.control is not None:
            self._stop_presses += 1
            self.abort("stop pressed")
        elif self.rig is not None and not self.wedged:
            if self._motions:
                self._end_motions("stop pressed")
            else:
                self._stop_verified("stop pressed")

    # ---- interlock alarm and the sample -------------------------------------------------
    def _set_alarm(self, message: str) -> None:
        self.alarm = message
        if message:
            self._alarm_at = time.monotonic()
        self.alarm_changed.emit(message)
        self._publish()

    def acknowledge(self) -> str:
        """Re-arm after a trip or fault: "" when done, else why not (the condition holds, or
        no instrument has answered since: only a fresh reading re-arms)."""
        if not self.alarm:
            return ""
        rig = self.rig
        if self.wedged:
            return "the rig does not answer: close gelrig and check the instruments"
        if rig is None:
            return "connect the rig first: only a fresh reading can re-arm"
        if self._motions:
            return "a manual motion is still going: wait for it to end"
        silent = self.silent()
        if silent:
            return f"not monitoring ({silent[0].text()}): wait for a fresh reading"
        if rig is not None:
            for interlock in rig.interlocks():
                value = self.values.get(interlock.column)
                at = self.read_at.get(interlock.column, 0.0)
                if value is None or at <= self._alarm_at:
                    return f"no fresh {interlock.name} reading yet: wait a moment"
                if interlock.headroom(value) <= 0:
                    return (f"{interlock.name} {value:.4g} {interlock.unit} is still beyond "
                            f"the limit {interlock.limit:g} {interlock.unit}: unload the "
                            "sample first")
        self._set_alarm("")
        return ""

    def _update_load(self, values: Mapping[str, float]) -> None:
        rig = self.rig
        reason = (rig.load_state(values) or "") if rig is not None else ""
        if reason != self.loaded:
            self.loaded = reason
            self.load_changed.emit(reason)
            self._publish()

    def unload(self) -> bool:
        """Move the sample to the rig's safe position (retract the plate, lift the arm)."""
        rig = self.rig
        if rig is None or self.running or self.wedged:
            return False
        self._end_motions("unloading")

        def done(safe: SafeState) -> None:
            self._set_safe(safe.line(), safe.verified)
            self.unloaded.emit(safe)
            self._publish()

        return self.worker.submit(
            lambda: still_loaded(rig, rig.unload(), lambda: rig.readings(MONITOR_RATE)),
            done=done, failed=lambda exc: self._failed("unload", exc))

    # ---- idle readouts ------------------------------------------------------------------
    def _poll(self) -> None:
        rig = self.rig
        if self._motions:  # the rig thread is watching a motion: show its values
            with self._live_lock:
                live, self._live = self._live, {}
            if live:
                self._on_readings(live, pending=False)
            return
        if rig is None or self.running or self._poll_pending or self.wedged:
            return
        self._poll_pending = True
        self.worker.submit(lambda: self._read(rig), done=self._on_readings,
                           failed=self._on_read_failed)

    def _answered_now(self, key: str) -> None:
        """On the rig thread, inside a readout: instrument ``key`` answered just now. Heard
        at once, so a stage read first is not called silent while the readout waits out a
        dead force input's deadline (seen under load: "KDC101 silent for 1 s" after the
        USB-6001 was killed). One dict item set: atomic under the GIL."""
        self.heard[key] = time.monotonic()

    def _on_readings(self, values: dict[str, float], pending: bool = True) -> None:
        if pending:
            self._poll_pending = False
        if self.running or self.rig is None:
            return
        now = time.monotonic()
        if isinstance(values, Readout):
            for key in values.answered:
                self.heard[key] = now
                self.faults.pop(key, None)
            for key, error in values.errors.items():
                if error != self.faults.get(key):  # the pane says it once, as NOT MONITORING
                    log.info("%s does not answer: %s", NAMES.get(key, key), error)
                self.faults[key] = error
        else:  # a guarded motion's values: their instruments answered
            for key in values:
                if key in SOURCE:
                    self.heard[SOURCE[key]] = now
        self.values.update(values)
        for key in values:
            self.read_at[key] = now
        if values:
            self.readings.emit(dict(values))
        complete = isinstance(values, Readout) and not values.errors
        if pending and complete:  # idle readouts only: a moving axis is not "loaded"
            self._update_load(self.values)
        self._publish()

    def _on_read_failed(self, exc: BaseException) -> None:
        self._poll_pending = False
        message = explain(exc)
        log.debug("readout: %s", message.detail, exc_info=exc)
        self.readings_failed.emit(message.text)

    # ---- the heartbeat and the one safety state ----------------------------------------
    def silent(self) -> tuple[Silent, ...]:
        """Instruments of the connected rig that have not answered lately (idle: the
        readout's; running: the run's sample blocks), with their last error."""
        rig = self.rig
        if rig is None:
            return ()
        now = time.monotonic()
        for key, at in list(self._run_heard.items()):
            self.heard[key] = max(self.heard.get(key, 0.0), at)
        limit = RUN_SILENT_AFTER if self.running else SILENT_AFTER
        busy = self._busy is not None or self._pending_busy
        out = []
        for key in rig.identities:
            since = now - self.heard.get(key, now)
            error = self.faults.get(key, "")
            if (error and not self.running) or (since > limit and not busy):
                out.append(Silent(NAMES.get(key, key), float(round(since, 1)), error))
        return tuple(out)

    def safety(self) -> Safety:
        """The one safety state every view renders."""
        rig = self.rig
        now = time.monotonic()
        busy = ""
        if self._busy is not None and now - self._busy[1] > SILENT_AFTER:
            busy = f"{self._busy[0]} in progress for {now - self._busy[1]:.0f} s"
        overlap: bool | None = None
        if isinstance(rig, CompressionRig):
            overlap = rig.first_touch is not None
        return Safety(
            connected=rig is not None, why_off=self._why_off, running=self.running,
            wedged=self.wedged, alarm=self.alarm, silent=self.silent(), busy=busy,
            safe_line=self.safe_line, safe_verified=self.safe_verified,
            pending=self.pending_text, loaded=self.loaded, overlap_armed=overlap,
            limits=limits_text(rig.limits if rig is not None else
                               self.spec.limits if self.spec is not None else None),
            values=dict(self.values),
            # whole seconds: the state changes (and the views redraw) once a second at most
            ages={key: float(round(now - at)) for key, at in self.read_at.items()
                  if key in self.values})

    def _publish(self) -> None:
        safety = self.safety()
        if safety != self._last_safety:
            self._last_safety = safety
            self.safety_changed.emit(safety)

    def _beat(self) -> None:
        """Every 250 ms: judge every instrument's silence, retry a pending safe stop once
        they all answer, and publish the state."""
        if self.running:
            latest = self.data.latest()
            if latest:
                now = time.monotonic()
                self.values.update(latest)
                for key in latest:
                    self.read_at[key] = self._run_heard.get(SOURCE.get(key, ""), now)
        self._retry_pending()
        self._publish()

    def _read(self, rig: Rig) -> Readout:
        """Live values of every instrument (rig thread), and which answered: the heartbeat.
        A failed readout names its instrument (the drivers' prefix); on the compression rig
        the stage answers first, so a failing force input leaves it heard, and a failing
        stage leaves the force input to be asked on its own. At 'as fast as possible' pace
        idle time would stand still, so it advances with the wall clock between readouts."""
        now = time.monotonic()
        clock = rig.clock
        if isinstance(clock, PacedClock) and math.isinf(clock.rate):
            clock.sleep(min(now - self._last_poll, 1.0))
        self._last_poll = now
        values: dict[str, float] = {"t_s": clock.now()}
        try:
            values.update(rig.readings(MONITOR_RATE, answered=self._answered_now))
        except Exception as exc:
            who = source_of(str(exc))
            errors = {key: explain(exc).text for key in rig.identities
                      if who is None or key == who}
            answered: set[str] = set()
            if isinstance(rig, CompressionRig) and who == "force":
                answered.add("stage")
                try:  # the stage's position stays live (not greyed) while the force is dead
                    values["position_m"] = rig.stage.position()
                except Exception as other:
                    answered.discard("stage")
                    errors["stage"] = explain(other).text
            elif isinstance(rig, CompressionRig) and who == "stage":
                try:
                    values["force_N"] = rig.force_now()
                    answered.add("force")
                except Exception as other:
                    errors["force"] = explain(other).text
            if str(exc) != self._last_trace:  # the traceback once per new error: the file
                self._last_trace = str(exc)
                log.debug("readout failed", exc_info=exc)
            return Readout({} if not answered else values, answered, errors)
        self._last_trace = ""
        return Readout(values, set(rig.identities), {})

    # ---- a run --------------------------------------------------------------------------
    def start_run(self, protocol: Procedure, info: RunInfo | None = None) -> Path:
        """Create the run directory (``info``: operator, note, tags for run.json, as
        ``gelrig run`` records them), wire the event stream, queue the run; returns its path.

        A protocol (file) whose steps the built rig's caps refuse raises
        :class:`Refused` before any folder is made (ADR 0330); a script's step refused
        before anything moved ends the run ``refused`` and its folder is taken away again
        (``refused`` is then the line, ``run_path`` None)."""
        rig, spec = self.rig, self.spec
        if rig is None or spec is None:
            raise GelrigError("connect the rig first")
        if self.running:
            raise GelrigError("a run is already going")
        if self.wedged:
            raise GelrigError("the rig is stuck in an instrument call: close gelrig, check "
                              "the instruments and start again")
        if self.alarm:
            raise GelrigError("an interlock tripped and is not acknowledged: Acknowledge on "
                              "the interlock banner first")
        self._end_motions("a run starts")
        control = RunControl()
        bus = EventBus()
        data = RunData()
        bridge = EventBridge(data, self)
        self.refused = ""
        refused = preflight(rig, protocol)  # the rig's caps, no instrument call
        if refused:
            raise Refused(f"{refused[0]}; refused before anything moves", protocol.source)
        root = self.services.runs_dir or Path("runs")
        out = default_run_dir(protocol, root)
        made = new_folders(out)
        run = create_run(protocol, spec, self.clock_spec(), out, info)
        try:  # refuses a protocol for the other rig
            host = RunHost(rig, protocol, run, bus=bus, control=control).__enter__()
        except BaseException:
            run.discard_empty()
            raise
        bridge.received.connect(self._on_event, Qt.ConnectionType.QueuedConnection)
        bus.subscribe(bridge)
        bus.subscribe(self._hear)
        self._monitor.stop()
        self.control, self.data, self._bridge, self.run_path = control, data, bridge, run.path
        self._host, self._stop_presses, self._stuck_said = host, 0, False
        self.values, self.loaded, self.read_at = {}, "", {}
        self._run_heard = {key: time.monotonic() for key in rig.identities}
        self.state = RunState.RUNNING
        self._watch.start()  # a fault (the watchdog) may abort the run without a press

        def task() -> RunState:
            """The run on the host's thread while the rig thread waits for it (one thread at
            a time on the instruments), so the host knows its outcome: a safe stop not
            confirmed is then pending, retried later (``complete_pending``)."""
            try:
                host.start()
                host.wait()
                outcome = host.outcome()
            finally:
                host.__exit__(None, None, None)
            problem = refused_unmoved(host)
            if problem:  # nothing moved: no run folder, as `gelrig run` (ADR 0330)
                discard_run(run, made)
                self.refused = f"{problem}; refused before anything moves"
            return outcome

        self.worker.submit(task, done=lambda state: self._run_done(state, host.reason),
                           failed=lambda exc: self._run_done(RunState.FAILED,
                                                             f"{type(exc).__name__}: {exc}"))
        self.run_started.emit(run.path)
        return run.path

    def _hear(self, event: Event) -> None:
        """The run's thread: a sample block is an answer from the instruments it holds."""
        if isinstance(event, Samples):
            now = time.monotonic()
            for key in event.data:
                source = SOURCE.get(key)
                if source is not None:
                    self._run_heard[source] = now

    def _on_event(self, event: object) -> None:
        if isinstance(event, InterlockTrip):
            self._set_alarm(event.message)
        elif isinstance(event, Fault):
            source = source_of(event.message)
            words = explain_fault(event.kind, event.message).text
            if source is not None:
                self.faults[source] = words
            self._set_alarm(f"fault: {words}")
        elif isinstance(event, SafeStopped):
            self._set_safe(event.state.line(), event.state.verified)
            self._publish()
        self.run_event.emit(event)

    def take_progress(self) -> Progress | None:
        return self._bridge.take_progress() if self._bridge is not None else None

    def pause(self) -> None:
        if self.control is not None:
            self.control.pause()

    def resume(self) -> None:
        if self.control is not None:
            self.control.resume()

    def abort(self, reason: str = "aborted from the GUI") -> None:
        if self.control is not None:
            self.control.abort(reason)
            self._watch.start()

    def end_hold(self) -> bool:
        """End the hold in progress now (data kept, the run goes on); False if none is."""
        return self.control is not None and self.control.end_hold()

    @property
    def holding(self) -> bool:
        return self.control is not None and self.control.holding

    # ---- a run that does not answer its abort (ADR 0070: the host's end from outside) ----
    def _watch_abort(self) -> None:
        """While a run goes: once it is stuck after an abort, a fault's (the watchdog's: nobody
        may be at the rig) is ended from outside at once, a person's by a second STOP (or
        closing); the result of that end is collected here too."""
        host = self._host
        if host is None or self.control is None:
            self._watch.stop()
            return
        if host.outside_end is not None:
            self._watch.stop()
            self._emergency_done(host)
            return
        if self.wedged or not host.stuck():
            return
        if self._stop_presses >= 2 or self._closing or self.control.fault_kind:
            self.wedged = True
            log.error("the run does not answer its abort: safe stop from outside the run")
            host.end_from_outside(wait=False)
        elif not self._stuck_said:
            self._stuck_said = True
            self.stuck.emit("the run does not answer the abort (stuck in an instrument call): "
                            "press STOP again to stop the rig from outside the run")

    def close_requested(self) -> None:
        """The window closes during a run: abort; a stuck run is ended from outside."""
        self._closing = True
        self.abort("the window was closed during the run")

    def _emergency_done(self, host: RunHost) -> None:
        """The host recorded the end from outside in run.json: end the run here."""
        safe = host.outside_end
        assert safe is not None
        self._monitor.stop()
        self.control, self._bridge = None, None
        self.state = RunState(host.outside_status)
        self._set_safe(safe.line(), safe.verified)
        self._set_alarm("the run was stuck and was ended from outside it")
        self.values = {}
        self.run_finished.emit(self.state, f"{safe.reason}; {safe.line()}")
        self.emergency_ended.emit(safe)

    def _run_done(self, state: RunState, reason: str) -> None:
        host, self._host = self._host, None
        if self.wedged:  # the stuck run came back after its emergency end
            self.wedged = False
            log.warning("the stuck run thread returned (%s); the rig answers again", reason)
            if self.rig is not None:
                self._monitor.start()
            return
        self.control = None
        self.values = {}  # re-arming waits for a reading at rest
        bridge, self._bridge = self._bridge, None  # it delivered every event it carried
        if bridge is not None:  # a child of the session: delete it, or it keeps the run's data
            bridge.deleteLater()
        self.state = state
        self.silent()  # the run's answers, kept in ``heard``
        self._run_heard = {}
        # The run's end talked to its instruments (its safe stop) with no sample blocks to
        # hear them by: one that did not fail is judged by the idle readouts from now on, not
        # called silent for the time the safe stop took (the walk of issue 25 saw "KDC101
        # silent for 2 s" after a run whose force input was killed; the stage had answered).
        ended = time.monotonic()
        for key in self.rig.identities if self.rig is not None else ():
            if key not in self.faults:
                self.heard[key] = max(self.heard.get(key, 0.0), ended)
        if self.refused:
            self.run_path, reason = None, self.refused
        if host is not None and host.pending is not None:
            self._pending, self._pending_since = host, time.monotonic()
            self.pending_text = ("SAFE STOP NOT CONFIRMED: retried once every instrument "
                                 "answers again")
            log.error("the safe stop is not confirmed; it is retried once the instruments "
                      "answer again (for up to %g s)", PENDING_LIMIT)
        if self.rig is not None:
            self._monitor.start()
        self.run_finished.emit(state, reason)
        self._publish()

    # ---- a safe stop not confirmed, retried (as ``complete_pending`` in the terminal) ----
    def _retry_pending(self) -> None:
        """Once every instrument answers again, run the pending safe stop again on the rig
        thread; the first verified one is recorded in run.json and said; given up after
        ``PENDING_LIMIT`` s."""
        host = self._pending
        if host is None or self._pending_busy or self.running or self.rig is None:
            return
        if time.monotonic() - self._pending_since > PENDING_LIMIT:
            self._pending = None
            self.pending_text = (f"SAFE STOP NOT COMPLETED within {PENDING_LIMIT:g} s - "
                                 "check the rig")
            log.error("the pending safe stop was not completed within %g s", PENDING_LIMIT)
            self.pending_done.emit(None)
            return
        if self.silent() or self._motions or self.wedged:
            return
        self._pending_busy = True

        def done(safe: SafeState | None) -> None:
            self._pending_busy = False
            if safe is None:
                return  # not yet: tried again at a later beat
            self._pending = None
            self.pending_text = f"safe stop completed later: {safe.line()}"
            self._set_safe(safe.line(), safe.verified)
            self.pending_done.emit(safe)
            self._publish()

        def failed(exc: BaseException) -> None:
            self._pending_busy = False
            log.error("retrying the safe stop: %s", exc)

        self.worker.submit(lambda: host.complete_pending(0.0, EMERGENCY_BUDGET), done=done,
                           failed=failed, urgent=True)

    # ---- the end ------------------------------------------------------------------------
    def shutdown(self, timeout: float = 30.0) -> bool:
        """Abort any run, close the rig (motion stopped first), end the rig thread."""
        self._monitor.stop()
        self._watch.stop()
        self._end_motions("the window was closed")
        if self.control is not None:
            self.control.abort("the window was closed")
        rig, self.rig = self.rig, None
        if rig is not None and not self.wedged:
            self.worker.submit(rig.close)
        elif rig is not None:  # the rig thread is stuck: close from here, bounded
            try:
                bounded(rig.close, 3.0, "closing the rig")
            except Exception as exc:
                log.error("closing the rig: %s", exc)
            timeout = min(timeout, 1.0)
        return self.worker.shutdown(timeout)

