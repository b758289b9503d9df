"""The main window at the rig: instruments, manual control, the protocol and its run, live
plots, the interlock banner and the log, and a Stop button that is never disabled."""

from __future__ import annotations

import logging
import math
import threading
import time
from pathlib import Path

from PySide6.QtCore import QObject, Qt, QTimer, QUrl, Signal
from PySide6.QtGui import QCloseEvent, QDesktopServices, QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QApplication,
    QComboBox,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QScrollArea,
    QSplitter,
    QStackedWidget,
    QTabWidget,
    QToolBar,
    QVBoxLayout,
    QWidget,
)

from gui import export, wheelguard
from gui.fit_panel import FitPanel
from gui.header import Header
from gui.instruments import InstrumentsPanel
from gui.interlocks import InterlockBanner
from gui.logpane import LogPane, QtLogHandler
from gui.manual import Command, ManualPanel
from gui.memory import release
from gui.messages import explain_fault, in_words
from gui.plots import CompressionPlots, IdlePlots, LivePlots, ShearPlots, configure
from gui.protocol_panel import ProtocolPanel, Rehearse
from gui.rigsession import RigSession
from gui.runview import RunWindow, step_lines
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
#: The window's preferred size (px); never larger than the screen's available area.
PREFERRED_SIZE = (1500, 950)


def fit_to_screen(window: QWidget) -> None:
    """Size ``window`` to its preferred size within the available screen area (the window
    frame allowed for), and place it at the area's top left."""
    screen = window.screen() or QApplication.primaryScreen()
    if screen is None:
        window.resize(*PREFERRED_SIZE)
        return
    area = screen.availableGeometry()
    frame_w, frame_h = 8, 32  # a typical title bar and border, before the frame is known
    width = min(PREFERRED_SIZE[0], area.width() - frame_w)
    height = min(PREFERRED_SIZE[1], area.height() - frame_h)
    window.resize(max(width, 200), max(height, 150))
    window.move(area.topLeft())


class _Done(QObject):
    """Carries a worker thread's result back to the GUI thread."""

    ready = Signal(object, object)  # callback, value


class MainWindow(QMainWindow):
    """Composes the panels around one :class:`RigSession`."""

    def __init__(self, services: Services, parent: QWidget | None = None):
        super().__init__(parent)
        configure()
        self.services = services
        self._rehearse_for: tuple[RigSpec, Rehearse] | None = None
        self.session = RigSession(services, self)
        app = QApplication.instance()
        if isinstance(app, QApplication):
            wheelguard.install(app)
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
        self.idle_plots = IdlePlots()
        self.fit_panel = FitPanel()
        self.header = Header(self.banner)
        self.stop_button = self.header.stop_button
        self.report_button = self.header.report_button
        self._done = _Done(self)
        self._done.ready.connect(lambda fn, value: fn(value),
                                 Qt.ConnectionType.QueuedConnection)
        self.shown_run: Path | None = None  # the run whose plots the window shows
        self.run_windows: list[RunWindow] = []
        self.last_message: QMessageBox | None = None
        self.close_after_run = False
        self._step_names: dict[int, str] = {}
        self._trouble: tuple[str, str] | None = None  # (title, text) awaiting its safe state
        self._next_draw = 0.0
        self._last_read_error = ""
        self._build_menus()
        self._build_toolbar()
        self._build_layout()
        self._wire()
        self.stop_shortcut = QShortcut(QKeySequence(Qt.Key.Key_Escape), self)
        self.stop_shortcut.setContext(Qt.ShortcutContext.ApplicationShortcut)
        self.stop_shortcut.activated.connect(self.stop)
        self._log_handler = QtLogHandler(self.log, logging.WARNING)
        logging.getLogger().addHandler(self._log_handler)
        self._timer = QTimer(self)
        self._timer.setInterval(REDRAW_MS)
        self._timer.timeout.connect(self._tick)
        self._timer.start()
        self.manual.set_kind(None)
        self._update_title()
        fit_to_screen(self)
        left = min(460, round(self.width() * 0.34))  # a third for the panels at most
        self.main_split.setSizes([left, self.width() - left])

    # ---- layout -------------------------------------------------------------------------
    def _build_menus(self) -> None:
        menu = self.menuBar().addMenu("&File")
        menu.addAction("Open &rig…", self.choose_rig)
        menu.addAction("Open &protocol…", QKeySequence.StandardKey.Open, self.choose_protocol)
        menu.addAction("Open r&un…", self.choose_run)
        menu.addSeparator()
        self.export_png_action = menu.addAction("Export plot as PN&G…", self.export_png)
        self.export_csv_action = menu.addAction("Export data as &CSV…", self.export_csv)
        self.report_action = menu.addAction("Open r&eport", self.open_report)
        self.report_action.setEnabled(False)
        menu.addSeparator()
        menu.addAction("&Quit", QKeySequence.StandardKey.Quit, self.close)
        help_menu = self.menuBar().addMenu("&Help")
        help_menu.addAction("&About gelrig", self.about)

    def _build_toolbar(self) -> None:
        bar = QToolBar("pace")
        bar.setMovable(False)
        self.addToolBar(bar)
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

    def _build_layout(self) -> None:
        """Header (banner, live values, STOP) above everything; left: protocol, manual
        control and instruments as tabs (each scrolls on its own); right: the run's plots or
        the live manual plot, above the log. Every part shrinks, so the window fits 1280x720
        and 2x scaling with STOP and the status bar in view."""
        self.left_tabs = QTabWidget()
        self.left_tabs.addTab(_scrolled(self.protocol), "Protocol")
        self.left_tabs.addTab(_scrolled(self.manual), "Manual control")
        self.left_tabs.addTab(_scrolled(self.instruments), "Instruments")
        self.plot_tabs = QTabWidget()
        self.plot_tabs.addTab(self.plot_stack, "Run")
        self.plot_tabs.addTab(self.idle_plots, "Manual (live)")
        self.plot_tabs.addTab(self.fit_panel, "Live fit")
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(self.plot_tabs)
        right.addWidget(self.log)
        right.setStretchFactor(0, 1)
        right.setSizes([700, 160])
        main = QSplitter(Qt.Orientation.Horizontal)
        main.addWidget(self.left_tabs)
        main.addWidget(right)
        main.setStretchFactor(1, 1)
        main.setSizes([460, 1040])
        self.main_split = main
        body = QWidget()
        column = QVBoxLayout(body)
        column.setContentsMargins(0, 0, 0, 0)
        column.setSpacing(0)
        column.addWidget(self.header)
        column.addWidget(main, 1)
        self.setCentralWidget(body)
        for widget in (self.left_tabs, self.plot_tabs, self.log, self.plot_stack):
            widget.setMinimumSize(0, 0)
        self.log.setMinimumHeight(40)
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
        self.report_button.clicked.connect(self.open_report)
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
        self.idle_plots.set_kind(spec.kind)
        self._update_title()
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
        self._update_title()

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
        self.header.show_live(values)
        self.idle_plots.add(values)
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
            self.plot_tabs.setCurrentWidget(self.idle_plots)

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

    def runs_dir(self) -> Path:
        """Where runs are recorded (``--runs``): Open run starts there."""
        folder = self.services.runs_dir or Path("runs")
        return folder if folder.is_dir() else Path.cwd()

    def choose_run(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Open a finished run",
                                                str(self.runs_dir()))
        if path:
            self.open_run(Path(path))

    def open_run(self, path: Path) -> RunWindow | None:
        try:
            window = RunWindow(path, self.services.analyze)
        except (GelrigError, OSError, KeyError) as exc:
            self.message("Open run", f"{path}: {exc}")
            return None
        window.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        window.destroyed.connect(lambda _=None, w=window: self._forget(w))
        self.run_windows.append(window)
        window.show()
        return window

    def _forget(self, window: RunWindow) -> None:
        """A closed run view: drop it (its data and curves go with it)."""
        if window in self.run_windows:
            self.run_windows.remove(window)
        release()

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
        release()  # the previous run's buffers and curves
        self.shown_run = path
        self._update_title()
        self.report_button.setVisible(False)
        self.report_action.setEnabled(False)
        self.plot_tabs.setCurrentIndex(0)
        self.left_tabs.setCurrentIndex(0)
        self.manual.set_enabled(False)
        self.instruments.set_connected(True, busy=True)
        self.protocol.set_state(RunState.RUNNING)
        self.statusBar().showMessage(f"running; recording to {path}")

    def _on_run_finished(self, state: RunState, reason: str) -> None:
        self.plots.refresh(self.session.data)
        release()  # what the runner and recorder held during the run
        words = in_words(reason)  # the raw reason goes to the log pane below
        self.protocol.set_state(state, words)
        connected = self.session.rig is not None
        self.manual.set_enabled(connected)
        self.instruments.set_connected(connected)
        self.statusBar().showMessage(f"run {state.value}: {words}; data in "
                                     f"{self.session.run_path}")
        self.log.add(f"run {state.value}: {reason}; data kept in {self.session.run_path}")
        self.report_button.setVisible(self.services.analyze is not None)
        self.report_action.setEnabled(self.services.analyze is not None)
        self._update_title()
        if self.close_after_run:
            self.close()

    def _on_event(self, event: object) -> None:
        self.fit_panel.on_event(event)
        if isinstance(event, StepStarted):
            self._step_names[event.index] = event.name
            self.log.add(f"step {event.index} started: {event.name} [{event.kind}]")
        elif isinstance(event, StepFinished):
            self.log.add(f"step {event.index} ({event.name}) {event.status}")
            for line in step_lines(dict(event.results)):
                self.log.add(f"step {event.index} result: {line.strip()}")
        elif isinstance(event, StateChanged):
            self.protocol.set_state(event.new, in_words(event.reason))
            self.log.add(f"{event.new.value}" + (f": {event.reason}" if event.reason else ""))
        elif isinstance(event, InterlockTrip):
            self.log.add(f"INTERLOCK {event.message}", "error")
            self._trouble = ("Interlock tripped", event.message)
        elif isinstance(event, Fault):
            words = explain_fault(event.kind, event.message)
            self.log.add(f"FAULT {words.detail}", "error")  # the wire detail: the log pane
            self._trouble = ("Fault: the run stopped", words.text)
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
            self.header.show_live(latest)

    # ---- title, export, report, about ---------------------------------------------------
    def _update_title(self) -> None:
        """'gelrig — <rig> (simulated) — run <dir> (running)'."""
        parts = ["gelrig"]
        spec = self.session.spec
        if spec is not None:
            parts.append(f"{spec.name} ({'simulated' if spec.simulated else 'hardware'})")
        if self.shown_run is not None:
            state = "running" if self.session.running else self.session.state.value
            parts.append(f"run {self.shown_run.name} ({state})")
        self.setWindowTitle(" — ".join(parts))

    def export_png(self, path: Path | None = None) -> Path | None:
        """The plots on show as a PNG (asks where unless ``path`` is given)."""
        widget = self.plot_tabs.currentWidget()
        if path is None:
            chosen, _ = QFileDialog.getSaveFileName(self, "Export plot as PNG",
                                                    str(self._export_start("plot.png")),
                                                    "PNG images (*.png)")
            if not chosen:
                return None
            path = Path(chosen)
        if not widget.grab().save(str(path), "PNG"):
            self.message("Export plot", f"{path}: could not write the image")
            return None
        self.log.add(f"plot exported to {path}")
        return path

    def export_csv(self, path: Path | None = None) -> Path | None:
        """The run's samples (the columns the plots use, one row per sample with its step
        index) as CSV; the full record stays in the run directory's HDF5 files."""
        data = self.session.data
        if not data.samples():
            self.message("Export data", "no run data to export yet: run a protocol first")
            return None
        if path is None:
            chosen, _ = QFileDialog.getSaveFileName(self, "Export data as CSV",
                                                    str(self._export_start("data.csv")),
                                                    "CSV files (*.csv)")
            if not chosen:
                return None
            path = Path(chosen)
        try:
            rows = export.write_csv(data, path)
        except OSError as exc:
            self.message("Export data", f"{path}: {exc.strerror or exc}")
            return None
        self.log.add(f"{rows} samples exported to {path}")
        return path

    def _export_start(self, name: str) -> Path:
        run = self.session.run_path
        return (run / name) if run is not None else self.runs_dir() / name

    def open_report(self) -> None:
        """The last run's HTML report in the browser (analysing the run first if needed)."""
        run, analyze = self.session.run_path, self.services.analyze
        if run is None or analyze is None:
            self.message("Open report", "no finished run to report on")
            return
        report = run / "analysis" / "report.html"
        if report.exists():
            self._show_report(report)
            return
        self.log.add(f"analysing {run} for its report…")
        self.report_button.setEnabled(False)

        def work() -> None:
            try:
                analyze(run)
                result: object = report
            except Exception as exc:  # shown, not raised: the GUI keeps running
                result = exc
            self._done.ready.emit(self._report_ready, result)

        threading.Thread(target=work, daemon=True, name="gelrig-report").start()

    def _report_ready(self, result: object) -> None:
        self.report_button.setEnabled(True)
        if isinstance(result, Path) and result.exists():
            self._show_report(result)
        else:
            self.log.add(f"no report: {result}", "error")
            self.message("Open report", f"the analysis wrote no report: {result}")

    def _show_report(self, report: Path) -> None:
        self.log.add(f"report: {report}")
        QDesktopServices.openUrl(QUrl.fromLocalFile(str(report.resolve())))

    def about(self) -> None:
        QMessageBox.about(self, "About gelrig",
                          "<b>gelrig</b>: contact mechanics of soft spheres — the plate-"
                          "compression rig (KDC101 stage, USB-6001 DAQ) and the MCR 501 shear "
                          "rig, their simulators, protocols in virtual time, analysis.<br><br>"
                          "STOP or Esc stops all motion at any time.")

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
        for window in list(self.run_windows):
            window.close()
        event.accept()


def _scrolled(widget: QWidget) -> QScrollArea:
    """``widget`` in a scroll area that lets it shrink (a small window scrolls it)."""
    scroll = QScrollArea()
    scroll.setWidgetResizable(True)
    scroll.setWidget(widget)
    scroll.setMinimumSize(0, 0)
    return scroll
