"""The main window at the rig: instruments, manual control, the protocol and its run, live
plots, the interlock banner and the log, and a Stop button that is never disabled."""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QCloseEvent
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QPushButton,
    QScrollArea,
    QSplitter,
    QStackedWidget,
    QToolBar,
    QVBoxLayout,
    QWidget,
)

from gui.instruments import InstrumentsPanel
from gui.interlocks import InterlockBanner
from gui.logpane import LogPane, QtLogHandler
from gui.manual import Command, ManualPanel
from gui.plots import CompressionPlots, LivePlots, ShearPlots, configure
from gui.protocol_panel import ProtocolPanel, Rehearse
from gui.rigsession import RigSession
from gui.runview import RunWindow
from gui.services import Services
from instrument.errors import GelrigError
from protocols.events import (
    Fault,
    Finished,
    InterlockTrip,
    RunState,
    SafeStopped,
    StateChanged,
    StepFinished,
    StepStarted,
)
from protocols.guard import Guarded
from protocols.rig import Rig
from protocols.rigfile import RigSpec
from protocols.safestop import SafeState

#: The pace control of simulated time.
PACES: tuple[tuple[str, float], ...] = (("1x", 1.0), ("10x", 10.0), ("100x", 100.0),
                                        ("as fast as possible", math.inf))
#: Plot redraw period (ms): about 25 Hz.
REDRAW_MS = 40
#: A redraw may take at most this share of the GUI thread's time (more points: fewer frames).
REDRAW_SHARE = 0.3
_STOP_STYLE = ("QPushButton { background:#c62828; color:white; font-weight:bold; "
               "padding:6px 18px; border-radius:4px; }")


class MainWindow(QMainWindow):
    """Composes the panels around one :class:`RigSession`."""

    def __init__(self, services: Services, parent: QWidget | None = None):
        super().__init__(parent)
        configure()
        self.services = services
        self._rehearse_for: tuple[RigSpec, Rehearse] | None = None
        self.session = RigSession(services, self)
        self.setWindowTitle("gelrig")
        self.instruments = InstrumentsPanel()
        self.manual = ManualPanel()
        self.protocol = ProtocolPanel()
        self.banner = InterlockBanner()
        self.banner.setObjectName("interlockBanner")
        self.log = LogPane()
        self.compression_plots = CompressionPlots()
        self.shear_plots = ShearPlots()
        self.plot_stack = QStackedWidget()
        self.plot_stack.addWidget(self.compression_plots)
        self.plot_stack.addWidget(self.shear_plots)
        self.run_windows: list[RunWindow] = []
        self.last_message: QMessageBox | None = None
        self.close_after_run = False
        self._step_names: dict[int, str] = {}
        self._trouble: tuple[str, str] | None = None  # (title, text) awaiting its safe state
        self._next_draw = 0.0
        self._last_read_error = ""
        self._build_toolbar()
        self._build_layout()
        self._wire()
        self._log_handler = QtLogHandler(self.log, logging.WARNING)
        logging.getLogger().addHandler(self._log_handler)
        self._timer = QTimer(self)
        self._timer.setInterval(REDRAW_MS)
        self._timer.timeout.connect(self._tick)
        self._timer.start()
        self.manual.set_kind(None)
        self.resize(1500, 950)

    # ---- layout -------------------------------------------------------------------------
    def _build_toolbar(self) -> None:
        bar = QToolBar("main")
        bar.setMovable(False)
        self.addToolBar(bar)
        bar.addAction("Open rig…", self.choose_rig)
        bar.addAction("Open protocol…", self.choose_protocol)
        bar.addAction("Open run…", self.choose_run)
        bar.addSeparator()
        bar.addWidget(QLabel(" pace of simulated time: "))
        self.pace_box = QComboBox()
        for label, rate in PACES:
            self.pace_box.addItem(label, rate)
        pace = self.services.pace
        index = next((i for i, (_l, r) in enumerate(PACES) if r == pace), -1)
        if index < 0:
            self.pace_box.addItem(f"{pace:g}x", pace)
            index = self.pace_box.count() - 1
        self.pace_box.setCurrentIndex(index)
        bar.addWidget(self.pace_box)
        spacer = QWidget()
        spacer.setSizePolicy(spacer.sizePolicy().horizontalPolicy().Expanding,
                             spacer.sizePolicy().verticalPolicy())
        bar.addWidget(spacer)
        self.stop_button = QPushButton("STOP")
        self.stop_button.setStyleSheet(_STOP_STYLE)
        self.stop_button.setToolTip("stop all motion now (aborts a run)")
        bar.addWidget(self.stop_button)

    def _build_layout(self) -> None:
        left_top = QWidget()
        column = QVBoxLayout(left_top)
        column.addWidget(self.instruments)
        column.addWidget(self.manual)
        column.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(left_top)
        left = QSplitter(Qt.Orientation.Vertical)
        left.addWidget(scroll)
        left.addWidget(self.protocol)
        left.setSizes([380, 560])
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(self.banner)
        right.addWidget(self.plot_stack)
        right.addWidget(self.log)
        right.setStretchFactor(1, 1)
        right.setSizes([40, 700, 160])
        main = QSplitter(Qt.Orientation.Horizontal)
        main.addWidget(left)
        main.addWidget(right)
        main.setSizes([480, 1020])
        self.setCentralWidget(main)
        self.statusBar().showMessage("starting")

    def _wire(self) -> None:
        s = self.session
        s.connected.connect(self._on_connected)
        s.disconnected.connect(self._on_disconnected)
        s.connect_failed.connect(self._on_connect_failed)
        s.readings.connect(self._on_readings)
        s.readings_failed.connect(self._on_readings_failed)
        s.command_failed.connect(self._on_command_failed)
        s.run_started.connect(self._on_run_started)
        s.run_finished.connect(self._on_run_finished)
        s.run_event.connect(self._on_event)
        s.motion_ended.connect(self._on_motion_ended)
        s.stuck.connect(self._on_stuck)
        s.emergency_ended.connect(self._on_emergency_ended)
        self.banner.bind(s, self.log.add)
        self.instruments.connect_clicked.connect(self.connect_rig)
        self.instruments.disconnect_clicked.connect(self.disconnect_rig)
        self.manual.command.connect(self._on_manual)
        self.protocol.open_clicked.connect(self.choose_protocol)
        self.protocol.run_clicked.connect(self.run_protocol)
        self.protocol.pause_clicked.connect(self.pause)
        self.protocol.resume_clicked.connect(self.resume)
        self.protocol.abort_clicked.connect(self.abort)
        self.stop_button.clicked.connect(self.stop)
        self.pace_box.currentIndexChanged.connect(self._on_pace)

    @property
    def plots(self) -> LivePlots:
        widget = self.plot_stack.currentWidget()
        assert isinstance(widget, LivePlots)
        return widget

    # ---- rig ----------------------------------------------------------------------------
    def start(self) -> None:
        """Load the rig file from the services and connect."""
        self.open_rig(self.services.rig_file)

    def open_rig(self, path: Path) -> None:
        if self.session.running:
            self.message("Open rig", "finish or abort the run first")
            return
        self.session.disconnect_rig()
        try:
            spec = self.session.load_rig(path)
        except GelrigError as exc:
            self.log.add(str(exc), "error")
            self.message("Rig file", str(exc))
            return
        self.instruments.set_spec(spec)
        self.instruments.set_state("connecting…")
        self.instruments.set_connected(False, busy=True)
        self.statusBar().showMessage("connecting…")
        self.banner.set_limits(spec.limits)
        self.plot_stack.setCurrentWidget(self.shear_plots if spec.kind == "shear"
                                         else self.compression_plots)
        self.pace_box.setEnabled(spec.simulated)
        self.protocol.set_pace(self.session.pace, real_time=not spec.simulated)
        self.protocol.set_rig(spec.kind, spec.limits, connected=False,
                              rehearse=self._rehearser(spec))
        self.log.add(f"rig {spec.name} ({spec.source}), "
                     f"{'simulated' if spec.simulated else 'hardware'}: connecting")
        self.session.connect_rig()

    def _rehearser(self, spec: RigSpec | None) -> Rehearse | None:
        """The rehearsal on ``spec``'s twin (one callable per rig file, so the panel keeps a
        finished rehearsal across connect and disconnect)."""
        rehearse = self.services.rehearse
        if spec is None or rehearse is None:
            return None
        if self._rehearse_for is None or self._rehearse_for[0] is not spec:
            self._rehearse_for = (spec, lambda protocol, control: rehearse(protocol, spec,
                                                                           control))
        return self._rehearse_for[1]

    def connect_rig(self) -> None:
        self.instruments.set_state("connecting…")
        self.instruments.set_connected(False, busy=True)
        self.session.connect_rig()

    def disconnect_rig(self) -> None:
        if not self.ask_if_loaded("Disconnect"):
            return
        self.instruments.set_state("disconnecting…")
        self.instruments.set_connected(True, busy=True)
        self.session.disconnect_rig()

    def _on_connected(self, rig: Rig) -> None:
        self.instruments.set_rig(rig)
        self.instruments.set_state(f"connected ({self.session.clock_spec()} clock)")
        self.instruments.set_connected(True)
        self.manual.set_kind(rig.kind)
        self.manual.set_enabled(True)
        self.protocol.set_rig(rig.kind, rig.limits, connected=True,
                              rehearse=self._rehearser(self.session.spec))
        self.statusBar().showMessage("connected")
        self.log.add(f"connected: {', '.join(rig.identities)}")

    def _on_disconnected(self) -> None:
        self.instruments.set_rig(None)
        self.instruments.set_state("disconnected")
        self.instruments.set_connected(False)
        self.manual.set_enabled(False)
        spec = self.session.spec
        self.protocol.set_rig(spec.kind if spec else None, spec.limits if spec else None, False,
                              rehearse=self._rehearser(spec))
        self.statusBar().showMessage("disconnected")
        self.log.add("disconnected")

    def _on_connect_failed(self, message: str) -> None:
        self.instruments.set_state("connection failed")
        self.instruments.set_connected(False)
        self.statusBar().showMessage("connection failed: not connected")
        self.log.add(f"connection failed: {message}", "error")
        self.message("Connection failed", message)

    def _on_readings(self, values: dict[str, float]) -> None:
        self.instruments.show_readings(values)
        self.manual.show_readings(values)
        self._last_read_error = ""

    def _on_readings_failed(self, message: str) -> None:
        if message != self._last_read_error:
            self._last_read_error = message
            self.log.add(f"readout: {message}", "warning")

    def _on_pace(self, index: int) -> None:
        rate = float(self.pace_box.itemData(index))
        self.session.set_pace(rate)
        self.protocol.set_pace(rate, real_time=not self.pace_box.isEnabled())
        self.log.add(f"pace of simulated time: {self.pace_box.itemText(index)}")

    # ---- manual control -----------------------------------------------------------------
    def _on_manual(self, what: str, command: Command) -> None:
        if self.session.command(what, command):
            self.log.add(what)

    def _on_motion_ended(self, result: Guarded) -> None:
        if result.outcome == "tripped":
            self.log.add(f"{result.what}: TRIPPED {result.reason}; motion stopped", "error")
            self.statusBar().showMessage("interlock tripped: motion stopped; unload, then "
                                         "Acknowledge on the banner")
            self.message("Interlock tripped", f"{result.what}: {result.reason}\n\nMotion was "
                         "stopped. Unload the sample, then Acknowledge on the banner.")
        elif result.outcome == "stopped":
            self.log.add(f"{result.what} stopped ({result.reason})")

    def _on_stuck(self, text: str) -> None:
        self.log.add(text, "error")
        self.protocol.status.setText(text)
        self.statusBar().showMessage("the run does not answer: press STOP again")

    def _on_emergency_ended(self, safe: SafeState) -> None:
        self.manual.set_enabled(False)  # the rig thread is stuck: nothing would be sent
        self.message("The run was stuck: stopped from outside it",
                     f"{safe.reason}\n\n{safe.line()}\n\nThe run is marked aborted and its "
                     "data kept. The rig does not answer: close gelrig and check the "
                     "instruments before the next run.")

    def ask_if_loaded(self, action: str) -> bool:
        """Before a run or a disconnect: True to go on; a loaded sample asks first."""
        if not self.session.loaded:
            return True
        answer = QMessageBox.question(
            self, "The sample is loaded",
            f"The sample is loaded ({self.session.loaded}). {action} all the same?\n"
            "(Unload to the safe position is on the interlock banner.)",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
            QMessageBox.StandardButton.No)
        return answer == QMessageBox.StandardButton.Yes

    def _on_command_failed(self, what: str, message: str) -> None:
        self.log.add(f"{what} failed: {message}; stopping all motion", "error")
        self.message(f"{what} failed", f"{message}\n\nAll motion was stopped.")

    def stop(self) -> None:
        """Stop everything now (abort a run; else stop every axis)."""
        self.log.add("STOP: stopping all motion", "warning")
        self.session.stop()

    # ---- protocol and run ---------------------------------------------------------------
    def choose_protocol(self) -> None:
        start = str(self.services.protocol_dir or Path.cwd())
        path, _ = QFileDialog.getOpenFileName(self, "Open protocol", start,
                                              "Protocol files (*.toml)")
        if path:
            self.protocol.load_file(Path(path))

    def choose_rig(self) -> None:
        start = str(self.services.rig_dir or Path.cwd())
        path, _ = QFileDialog.getOpenFileName(self, "Open rig file", start, "Rig files (*.toml)")
        if path:
            self.open_rig(Path(path))

    def choose_run(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Open a finished run", str(Path.cwd()))
        if path:
            self.open_run(Path(path))

    def open_run(self, path: Path) -> RunWindow | None:
        try:
            window = RunWindow(path, self.services.analyze)
        except (GelrigError, OSError, KeyError) as exc:
            self.message("Open run", f"{path}: {exc}")
            return None
        self.run_windows.append(window)
        window.show()
        return window

    def run_protocol(self) -> None:
        spec = self.protocol.spec
        if spec is None or self.protocol.why_not or not self.ask_if_loaded("Start the run"):
            return
        try:
            path = self.session.start_run(spec)
        except (GelrigError, OSError) as exc:
            self.log.add(f"cannot start the run: {exc}", "error")
            self.message("Cannot start the run", str(exc))
            return
        self.log.add(f"run of {spec.name!r} started; recording to {path}")

    def pause(self) -> None:
        """Pause at the next checkpoint; during a hold, offer to end it or abort instead."""
        if self.session.holding:
            choice = self.protocol.ask_hold()
            if choice == "end":
                if self.session.end_hold():
                    self.protocol.hold_ending()
                    self.log.add("ending the hold now (its data is kept; the run goes on)")
                else:
                    self.log.add("the hold had already ended")
            elif choice == "abort":
                self.abort()
            return
        self.session.pause()
        self.protocol.request_pause()
        self.log.add("pause requested (takes effect at the next checkpoint)")

    def resume(self) -> None:
        self.session.resume()
        self.protocol.cancel_pause()
        self.log.add("resume")

    def abort(self) -> None:
        self.session.abort("aborted from the GUI")
        self.log.add("abort requested: stopping all motion", "warning")

    def _on_run_started(self, path: Path) -> None:
        self._step_names.clear()
        self.plots.clear()
        self.manual.set_enabled(False)
        self.instruments.set_connected(True, busy=True)
        self.protocol.set_state(RunState.RUNNING)
        self.statusBar().showMessage(f"running; recording to {path}")

    def _on_run_finished(self, state: RunState, reason: str) -> None:
        self.plots.refresh(self.session.data)
        self.protocol.set_state(state, reason)
        connected = self.session.rig is not None
        self.manual.set_enabled(connected)
        self.instruments.set_connected(connected)
        self.statusBar().showMessage(f"run {state.value}: {reason}; data in "
                                     f"{self.session.run_path}")
        self.log.add(f"run {state.value}: {reason}; data kept in {self.session.run_path}")
        if self.close_after_run:
            self.close()

    def _on_event(self, event: object) -> None:
        if isinstance(event, StepStarted):
            self._step_names[event.index] = event.name
            self.log.add(f"step {event.index} started: {event.name} [{event.kind}]")
        elif isinstance(event, StepFinished):
            self.log.add(f"step {event.index} ({event.name}) {event.status}")
        elif isinstance(event, StateChanged):
            self.protocol.set_state(event.new, event.reason)
            self.log.add(f"{event.new.value}" + (f": {event.reason}" if event.reason else ""))
        elif isinstance(event, InterlockTrip):
            self.log.add(f"INTERLOCK {event.message}", "error")
            self._trouble = ("Interlock tripped", event.message)
        elif isinstance(event, Fault):
            self.log.add(f"FAULT {event.kind}: {event.message}", "error")
            self._trouble = ("Fault: the run stopped", f"{event.kind}: {event.message}")
        elif isinstance(event, SafeStopped):  # the same one line as the CLI's
            line = event.state.line()
            self.log.add(line, "warning" if event.state.verified else "error")
            title, text = self._trouble or ("Run aborted", event.state.reason)
            self._trouble = None
            self.message(title, f"{text}\n\n{line}\n\nThe data recorded so far is kept.")
        elif isinstance(event, Finished):
            self.log.add(f"finished: {event.state.value}")

    # ---- the live view ------------------------------------------------------------------
    def _tick(self) -> None:
        """Redraw from the buffers at up to 25 Hz, fewer frames when a frame is costly."""
        if not self.session.running:
            return
        progress = self.session.take_progress()
        if progress is not None:
            self.protocol.show_progress(progress, self._step_names.get(progress.index, ""))
        now = time.perf_counter()
        if now < self._next_draw:
            return
        if self.plots.refresh(self.session.data):
            self.plots.paint_now()
            cost = time.perf_counter() - now
            self._next_draw = now + cost / REDRAW_SHARE
        latest = self.session.data.latest()
        if latest:
            self.instruments.show_readings(latest)
            self.banner.live(latest)

    def message(self, title: str, text: str) -> QMessageBox:
        """A clear, non-blocking message box (the GUI keeps running behind it)."""
        box = QMessageBox(QMessageBox.Icon.Critical, title, text, QMessageBox.StandardButton.Ok,
                          self)
        box.setObjectName("faultMessage")
        box.open()
        self.last_message = box
        return box

    # ---- closing ------------------------------------------------------------------------
    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt override)
        """Mid-run: ask, then abort (motion stops), keep the data, close when the run ended."""
        if self.session.running:
            if not self.close_after_run:
                answer = QMessageBox.question(
                    self, "A run is in progress",
                    "A protocol is running. Abort it (all motion stops at once) and close?\n"
                    "The data recorded so far is kept.",
                    QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                    QMessageBox.StandardButton.No)
                if answer != QMessageBox.StandardButton.Yes:
                    event.ignore()
                    return
                self.close_after_run = True
                self.session.close_requested()
                self.log.add("aborting the run before closing", "warning")
            event.ignore()
            return
        self._timer.stop()
        self.protocol.cancel_rehearsal()
        logging.getLogger().removeHandler(self._log_handler)
        self.session.shutdown()
        for window in self.run_windows:
            window.close()
        event.accept()
