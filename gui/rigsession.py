"""The rig as the GUI drives it: connect, idle readouts, manual commands, one run at a time.

Not a widget: panels call it and listen to its signals. Every instrument call goes through
the single :class:`~gui.tasks.RigThread`; a run is wired by the same
:class:`~protocols.session.RecordedRun` as ``gelrig run`` (its Recorder a critical
subscriber), so closing the window or a fault never loses data.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from PySide6.QtCore import QObject, Qt, QTimer, Signal

from gui.bridge import EventBridge
from gui.messages import explain, explain_fault
from gui.rundata import RunData
from gui.services import Services
from gui.tasks import RigThread
from instrument.clock import Clock, PacedClock, RealClock
from instrument.errors import GelrigError
from instrument.store import RunDirectory
from protocols.control import RunControl
from protocols.events import EventBus, Fault, InterlockTrip, Progress, RunState
from protocols.guard import Guarded, Motion, run_motion
from protocols.rig import Rig
from protocols.rigfile import RigSpec
from protocols.safestop import AxisState, SafeState, bounded
from protocols.session import RecordedRun
from protocols.spec import ProtocolSpec

log = logging.getLogger(__name__)

#: Force sample rate (Hz) of the idle readout (the USB-6001's lowest; a run restarts the
#: acquisition at its own rate if different).
MONITOR_RATE = 100.0
#: Idle readout period (s, wall time).
MONITOR_PERIOD = 0.2
#: Wall seconds an aborted run has to begin its own safe stop before it counts as stuck
#: (as ``gelrig run``'s GRACE).
GRACE = 3.0
#: Wall-time budget of the safe stop the GUI runs itself when the run is stuck.
EMERGENCY_BUDGET = 12.0


def clock_spec(clock: Clock | None, pace: float) -> str:
    """The clock as ``gelrig run --clock`` would name it (stored in run.json)."""
    if isinstance(clock, RealClock):
        return "real"
    return "paced:inf" if math.isinf(pace) else f"paced:{pace:g}"


def unique_dir(path: Path) -> Path:
    """``path``, or ``path-2``, ``path-3``... if a run is already there."""
    candidate, k = path, 2
    while (candidate / "run.json").exists():
        candidate = path.with_name(f"{path.name}-{k}")
        k += 1
    return candidate


class RigSession(QObject):
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
        self._recorded: RecordedRun | None = None
        self._run_dir: RunDirectory | None = None
        self._stop_presses = 0
        self._closing = False
        self.wedged = False  # the rig thread is stuck in an instrument call
        self._emergency: list[SafeState] = []  # the emergency safe stop's result (its thread)
        self._stuck_said = False
        self._watch = QTimer(self)
        self._watch.setInterval(250)
        self._watch.timeout.connect(self._watch_abort)

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
        clock: Clock = PacedClock(self.pace) if spec.simulated else RealClock()
        self._connecting = True
        self.worker.submit(lambda: self.services.build_rig(spec, clock),
                           done=self._on_connected, failed=self._on_connect_failed)

    def _on_connected(self, rig: Rig) -> None:
        self._connecting = False
        self.rig = rig
        self._monitor.start()
        self.connected.emit(rig)

    def _on_connect_failed(self, exc: BaseException) -> None:
        self._connecting = False
        message = explain(exc)
        log.warning("connecting the rig: %s", message.detail)
        self.connect_failed.emit(message.text)

    def disconnect_rig(self) -> None:
        if self.rig is None or self.running:
            return
        self._monitor.stop()
        self._end_motions("disconnecting")
        rig, self.rig = self.rig, None
        self.values, self.loaded = {}, ""
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
            return self.worker.submit(lambda: fn(rig),
                                      failed=lambda exc: self._failed(what, exc))
        control = RunControl()
        self._motions.append(control)
        tripped = bool(self.alarm)

        def task() -> Guarded:
            return run_motion(rig, what, fn, control, self._set_live, tripped)

        def done(result: Guarded) -> None:
            self._motion_over(control)
            self.values = {}  # what the motion saw is not a reading at rest: read again
            if result.outcome == "tripped":
                self._set_alarm(result.reason)
            self.motion_ended.emit(result)

        def failed(exc: BaseException) -> None:
            self._motion_over(control)
            self.values = {}
            self._failed(what, exc)

        return self.worker.submit(task, done=done, failed=failed)

    def _set_live(self, values: dict[str, float]) -> None:
        """A guarded motion's newest values (rig thread); the readout timer shows them."""
        with self._live_lock:
            self._live.update(values)

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
        message = explain(exc)
        log.warning("%s failed: %s", what, message.detail)  # the wire detail: the log pane
        self.command_failed.emit(what, message.text)
        if self.rig is not None and not self.wedged:
            self.worker.submit(self.rig.stop_all, urgent=True)

    def stop(self) -> None:
        """Stop all motion now: abort the run if one is going (pressed again while the run
        does not answer: the emergency end), else stop every axis."""
        if self.control is not None:
            self._stop_presses += 1
            self.abort("stop pressed")
        elif self.rig is not None and not self.wedged:
            self._end_motions("stop pressed")
            self.worker.submit(self.rig.stop_all, urgent=True)

    # ---- interlock alarm and the sample -------------------------------------------------
    def _set_alarm(self, message: str) -> None:
        self.alarm = message
        self.alarm_changed.emit(message)

    def acknowledge(self) -> str:
        """Re-arm after a trip or fault: "" when done, else why not (the condition holds)."""
        if not self.alarm:
            return ""
        rig = self.rig
        if self.wedged:
            return "the rig does not answer: close gelrig and check the instruments"
        if self._motions:
            return "a manual motion is still going: wait for it to end"
        if rig is not None:
            for interlock in rig.interlocks():
                value = self.values.get(interlock.column)
                if value is None:
                    return f"no live {interlock.name} reading yet: wait a moment"
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

    def unload(self) -> bool:
        """Move the sample to the rig's safe position (retract the plate, lift the arm)."""
        rig = self.rig
        if rig is None or self.running or self.wedged:
            return False
        self._end_motions("unloading")
        return self.worker.submit(rig.unload, done=self.unloaded.emit,
                                  failed=lambda exc: self._failed("unload", exc))

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

    def _on_readings(self, values: dict[str, float], pending: bool = True) -> None:
        if pending:
            self._poll_pending = False
        if not self.running and self.rig is not None:
            self.values.update(values)
            self.readings.emit(values)
            if pending:  # idle readouts only: a moving axis is not "loaded"
                self._update_load(self.values)

    def _on_read_failed(self, exc: BaseException) -> None:
        self._poll_pending = False
        message = explain(exc)
        log.debug("readout: %s", message.detail)
        self.readings_failed.emit(message.text)

    def _read(self, rig: Rig) -> dict[str, float]:
        """Live values of every instrument (rig thread). At 'as fast as possible' pace idle
        time would stand still, so it advances with the wall clock between readouts."""
        now = time.monotonic()
        clock = rig.clock
        if isinstance(clock, PacedClock) and math.isinf(clock.rate):
            clock.sleep(min(now - self._last_poll, 1.0))
        self._last_poll = now
        values: dict[str, float] = {"t_s": clock.now()}
        values.update(rig.readings(MONITOR_RATE))
        return values

    # ---- a run --------------------------------------------------------------------------
    def start_run(self, protocol: ProtocolSpec) -> Path:
        """Create the run directory, wire the event stream, queue the run; returns its path."""
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
        recorded = RecordedRun(rig, protocol, bus, control)  # refuses a protocol for the other rig
        path = unique_dir(self.services.default_run_dir(protocol))
        run = RunDirectory.create(path, self.services.metadata(protocol, spec, self.clock_spec()))
        recorded.record(run)
        bridge.received.connect(self._on_event, Qt.ConnectionType.QueuedConnection)
        bus.subscribe(bridge)
        self._monitor.stop()
        self.control, self.data, self._bridge, self.run_path = control, data, bridge, run.path
        self._recorded, self._run_dir, self._stop_presses = recorded, run, 0
        self._emergency, self._stuck_said = [], False
        self.values, self.loaded = {}, ""
        self.state = RunState.RUNNING

        def task() -> RunState:
            rig.end_monitoring()  # the run starts its own acquisition
            return recorded.run()

        self.worker.submit(task, done=lambda state: self._run_done(state, recorded.reason),
                           failed=lambda exc: self._run_done(RunState.FAILED,
                                                             f"{type(exc).__name__}: {exc}"))
        self.run_started.emit(run.path)
        return run.path


    def _on_event(self, event: object) -> None:
        if isinstance(event, InterlockTrip):
            self._set_alarm(event.message)
        elif isinstance(event, Fault):
            self._set_alarm(f"fault: {explain_fault(event.kind, event.message).text}")
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

    # ---- a run that does not answer its abort (ADR 0070, as ``gelrig run``) -------------
    def _is_stuck(self) -> bool:
        control, recorded = self.control, self._recorded
        if control is None or recorded is None or control.abort_time is None:
            return False
        waited = time.monotonic() - control.abort_time
        if recorded.runner.ending:  # in its own safe stop: give it its budget
            return waited > GRACE + EMERGENCY_BUDGET + 5.0
        return waited > GRACE

    def _watch_abort(self) -> None:
        """After an abort: once the run is stuck, a second STOP (or closing) ends it from
        here; the emergency safe stop's result is collected here too."""
        if self._emergency:
            self._watch.stop()
            self._emergency_done(self._emergency.pop())
            return
        if self.control is None:
            self._watch.stop()
            return
        if not self._is_stuck() or self.wedged:
            return
        if self._stop_presses >= 2 or self._closing:
            self._emergency_stop()
        elif not self._stuck_said:
            self._stuck_said = True
            self.stuck.emit("the run does not answer the abort (stuck in an instrument call): "
                            "press STOP again to stop the rig from outside the run")

    def close_requested(self) -> None:
        """The window closes during a run: abort; a stuck run is ended from outside."""
        self._closing = True
        self.abort("the window was closed during the run")

    def _emergency_stop(self) -> None:
        """The rig's safe stop from a thread of its own, every call bounded (the rig thread
        is stuck in an instrument call that ignores its deadline)."""
        recorded, control = self._recorded, self.control
        if recorded is None or control is None:
            return
        self.wedged = True
        reason = control.abort_reason + " (the run was stuck in an instrument call)"
        log.error("the run does not answer its abort: safe stop from outside the run")
        out = self._emergency
        rig = recorded.rig

        def work() -> None:  # touches no Qt object: the watch timer collects the result
            try:
                safe = bounded(lambda: rig.safe_stop(reason, EMERGENCY_BUDGET),
                               EMERGENCY_BUDGET + 2.0, "safe stop")
            except Exception as exc:
                safe = SafeState(reason, [AxisState(name, "", stop_sent=True,
                                                    errors=[str(exc)])
                                          for name in rig.identities])
            out.append(safe)

        threading.Thread(target=work, name="gelrig-emergency-stop", daemon=True).start()

    def _emergency_done(self, safe: SafeState) -> None:
        """Record the end in run.json (aborted, the safe state) and end the run here."""
        log.log(logging.WARNING if safe.verified else logging.ERROR, "safe stop: %s",
                safe.line())
        run = self._run_dir
        if run is not None:
            try:
                meta = run.read_metadata()
                meta.update(status="aborted", reason=safe.reason, safe_state=safe.as_dict())
                run.write_metadata(meta)
            except Exception as exc:
                log.error("could not record the end in run.json: %s", exc, exc_info=True)
        self._monitor.stop()
        self.control, self._bridge = None, None
        self.state = RunState.ABORTED
        self._set_alarm("the run was stuck and was ended from outside it")
        self.values = {}
        self.run_finished.emit(RunState.ABORTED, f"{safe.reason}; {safe.line()}")
        self.emergency_ended.emit(safe)

    def _run_done(self, state: RunState, reason: str) -> None:
        self._recorded = None
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
        if self.rig is not None:
            self._monitor.start()
        self.run_finished.emit(state, reason)

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

