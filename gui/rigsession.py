"""The rig as the GUI drives it: connect, idle readouts, manual commands, one run at a time.

Not a widget: panels call it and listen to its signals. Every instrument call goes through
the single :class:`~gui.tasks.RigThread`; a run is wired by the same
:class:`~protocols.session.RecordedRun` as ``gelrig run`` (its Recorder a critical
subscriber), so closing the window or a fault never loses data.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject, Qt, QTimer, Signal

from gui.bridge import EventBridge
from gui.rundata import RunData
from gui.services import Services
from gui.tasks import RigThread
from instrument.clock import Clock, PacedClock, RealClock
from instrument.errors import GelrigError
from instrument.store import RunDirectory
from protocols.control import RunControl
from protocols.events import EventBus, Progress, RunState
from protocols.rig import Rig
from protocols.rigfile import RigSpec
from protocols.session import RecordedRun
from protocols.spec import ProtocolSpec

log = logging.getLogger(__name__)

#: Force sample rate (Hz) of the idle readout (the USB-6001's lowest; a run restarts the
#: acquisition at its own rate if different).
MONITOR_RATE = 100.0
#: Idle readout period (s, wall time).
MONITOR_PERIOD = 0.2


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
        self.connect_failed.emit(f"{type(exc).__name__}: {exc}")

    def disconnect_rig(self) -> None:
        if self.rig is None or self.running:
            return
        self._monitor.stop()
        rig, self.rig = self.rig, None
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
    def command(self, what: str, fn: Callable[[Rig], object]) -> bool:
        """Run a manual command on the rig thread; refused during a run."""
        rig = self.rig
        if rig is None or self.running:
            return False
        return self.worker.submit(lambda: fn(rig), failed=lambda exc: self._failed(what, exc))

    def _failed(self, what: str, exc: BaseException) -> None:
        self.command_failed.emit(what, f"{type(exc).__name__}: {exc}")
        if self.rig is not None:
            self.worker.submit(self.rig.stop_all, urgent=True)

    def stop(self) -> None:
        """Stop all motion now: abort the run if one is going, else stop every axis."""
        if self.control is not None:
            self.control.abort("stop pressed")
        elif self.rig is not None:
            self.worker.submit(self.rig.stop_all, urgent=True)

    # ---- idle readouts ------------------------------------------------------------------
    def _poll(self) -> None:
        rig = self.rig
        if rig is None or self.running or self._poll_pending:
            return
        self._poll_pending = True
        self.worker.submit(lambda: self._read(rig), done=self._on_readings,
                           failed=self._on_read_failed)

    def _on_readings(self, values: dict[str, float]) -> None:
        self._poll_pending = False
        if not self.running:
            self.readings.emit(values)

    def _on_read_failed(self, exc: BaseException) -> None:
        self._poll_pending = False
        self.readings_failed.emit(f"{type(exc).__name__}: {exc}")

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

    def _run_done(self, state: RunState, reason: str) -> None:
        self.control = None
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
        if self.control is not None:
            self.control.abort("the window was closed")
        rig, self.rig = self.rig, None
        if rig is not None:
            self.worker.submit(rig.close)
        return self.worker.shutdown(timeout)

