"""The main window at the rig: instruments, manual control, the protocol and its run, live
plots, the interlock banner and the log, and a Stop button that is never disabled."""

from __future__ import annotations

import logging
import math
import os
import time
import weakref
from collections.abc import Callable
from functools import partial
from pathlib import Path

from PySide6.QtCore import (
    QByteArray,
    QMetaObject,
    QSettings,
    Qt,
    QTimer,
    QUrl,
)
from PySide6.QtGui import (
    QAction,
    QActionGroup,
    QCloseEvent,
    QDesktopServices,
    QGuiApplication,
    QKeySequence,
)
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

from gelrig.gui import dialogs, export, offthread, theme, wheelguard
from gelrig.gui.desk import RigDesk
from gelrig.gui.fit_panel import FitPanel
from gelrig.gui.header import Header, StatusLine
from gelrig.gui.instruments import InstrumentsPanel
from gelrig.gui.interlocks import InterlockBanner
from gelrig.gui.logpane import LogPane, QtLogHandler, file_log
from gelrig.gui.manual import Command, ManualPanel
from gelrig.gui.memory import release
from gelrig.gui.messages import explain_fault, in_words
from gelrig.gui.plots import CompressionPlots, IdlePlots, LivePlots, ShearPlots, configure
from gelrig.gui.protocol_panel import ProtocolPanel, Rehearse
from gelrig.gui.queue import QueuePanel
from gelrig.gui.queue_items import QueueItem
from gelrig.gui.queue_runner import QueueRunner
from gelrig.gui.results_browser import ResultsBrowser
from gelrig.gui.run_info_form import load_info, save_info
from gelrig.gui.runview import RunWindow, step_lines
from gelrig.gui.runview import fit_to_screen as fit
from gelrig.gui.safety import Safety
from gelrig.gui.sample_form import load_texts, save_texts
from gelrig.gui.services import Services
from gelrig.instrument.core.errors import GelrigError, Refused
from gelrig.protocols.events import (
    Fault,
    Finished,
    InterlockTrip,
    RunState,
    SafeStopped,
    StateChanged,
    StepFinished,
    StepStarted,
)
from gelrig.protocols.manual_motion import Guarded
from gelrig.protocols.plan import dry_run
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rig import Rig
from gelrig.protocols.rigfile import RigSpec
from gelrig.protocols.runinfo import RunInfo
from gelrig.protocols.safestop import SafeState
from gelrig.protocols.spec import ProtocolSpec

#: The pace control of simulated time.
PACES: tuple[tuple[str, float], ...] = (("1x", 1.0), ("10x", 10.0), ("100x", 100.0),
                                        ("as fast as possible", math.inf))
#: Plot redraw period (ms): about 25 Hz.
REDRAW_MS = 40
#: A redraw may take at most this share of the GUI thread's time (more points: fewer frames).
REDRAW_SHARE = 0.3
#: The window's preferred size (px); never larger than the screen's available area.
PREFERRED_SIZE = (1500, 950)


#: How many recent protocols File > Recent protocols keeps.
RECENT = 8


def settings() -> QSettings:
    """Where the window remembers its size, place, splitters and recent protocols (an INI
    file in the user's configuration folder; ``GELRIG_SETTINGS`` names another)."""
    path = os.environ.get("GELRIG_SETTINGS")
    if path:
        return QSettings(path, QSettings.Format.IniFormat)
    return QSettings(QSettings.Format.IniFormat, QSettings.Scope.UserScope, "gelrig", "gui")


def queue_file() -> Path:
    """Where the queue is kept: ``gelrig-queue.json`` beside the settings file."""
    return Path(settings().fileName()).with_name("gelrig-queue.json")


def fit_to_screen(window: QWidget) -> None:
    """Size ``window`` to :data:`PREFERRED_SIZE` within the available screen area."""
    fit(window, PREFERRED_SIZE)


class MainWindow(QMainWindow):
    """Composes the panels around one :class:`RigDesk`."""

    def __init__(self, services: Services, parent: QWidget | None = None):
        super().__init__(parent)
        configure()
        self.services = services
        self._rehearse_for: tuple[RigSpec, Rehearse] | None = None
        self.desk = RigDesk(services, self)
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
        self.results = ResultsBrowser(services.runs_dir or Path("runs"), self.open_run,
                                      lambda line: self.log.add(line, "warning"))
        self.queue_runner = QueueRunner(self.desk, lambda: self._rehearser(self.desk.spec),
                                        self.start_queued, queue_file(), self)
        self.queue_runner.said.connect(self.log.add)
        if self.queue_runner.warning:
            self.log.add(self.queue_runner.warning, "warning")
        self.queue = QueuePanel(self.queue_runner, self._queue_item,
                                lambda then: self.ask_if_loaded("Start the queue", then))
        self.header = Header(self.banner)
        self.stop_button = self.header.stop_button
        self.report_button = self.header.report_button
        self.shown_run: Path | None = None  # the run whose plots the window shows
        self.run_windows: list[RunWindow] = []
        self.last_message: QMessageBox | None = None
        self.close_after_run = False
        self._step_names: dict[int, str] = {}
        self._trouble: tuple[str, str] | None = None  # (title, text) awaiting its safe state
        self._next_draw = 0.0
        self._last_read_error = ""
        self._said_silent = ""
        self._build_menus()
        self._build_toolbar()
        self._build_layout()
        self._wire()
        self._escape = dialogs.EscapeStops(self.stop, self)  # Esc: STOP, over any dialog
        self._escape.install()
        self._close_box: QMessageBox | None = None
        self._leave_loaded = False
        self._close_after_unload = False
        self._log_handler = QtLogHandler(self.log, logging.WARNING)
        logging.getLogger().addHandler(self._log_handler)
        self._file_log = file_log(self.services.runs_dir or Path("runs"))
        if self._file_log is not None:
            logging.getLogger().addHandler(self._file_log[0])
            self.log.add(f"details and tracebacks: {self._file_log[1]}")
        self._timer = QTimer(self)
        self._timer.setInterval(REDRAW_MS)
        self._timer.timeout.connect(self._tick)
        self._timer.start()
        self.manual.set_kind(None)
        self._update_title()
        fit_to_screen(self)
        left = min(460, round(self.width() * 0.34))  # a third for the panels at most
        self.main_split.setSizes([left, self.width() - left])
        self._restore_settings()

    # ---- layout -------------------------------------------------------------------------
    def _build_menus(self) -> None:
        menu = self.menuBar().addMenu("&File")
        menu.addAction("Open &rig…", self.choose_rig)
        menu.addAction("Open &protocol…", QKeySequence.StandardKey.Open, self.choose_protocol)
        menu.addAction("Open r&un…", self.choose_run)
        self.recent_menu = menu.addMenu("Recent &protocols")
        self.recent: list[str] = []
        self.save_action = menu.addAction("&Save protocol", QKeySequence.StandardKey.Save,
                                          self.save_protocol)
        self.save_as_action = menu.addAction("Save protocol &as…",
                                             QKeySequence.StandardKey.SaveAs,
                                             self.save_protocol_as)
        menu.addSeparator()
        self.export_png_action = menu.addAction("Export plot as PN&G…", self.export_png)
        self.export_csv_action = menu.addAction("Export data as &CSV…", self.export_csv)
        self.report_action = menu.addAction("Open r&eport", self.open_report)
        self.report_action.setEnabled(False)
        menu.addSeparator()
        menu.addAction("&Quit", QKeySequence.StandardKey.Quit, self.close)
        rig_menu = self.menuBar().addMenu("&Rig")
        self.run_action = rig_menu.addAction("&Run the protocol", QKeySequence("Ctrl+R"),
                                             self.run_protocol)
        self.pause_action = rig_menu.addAction("&Pause", QKeySequence("Ctrl+P"), self.pause)
        rig_menu.addAction("&Home the stage", QKeySequence("Ctrl+H"), self.home_stage)
        stop = rig_menu.addAction("&STOP all motion (Esc)", self.stop)
        stop.setToolTip("Esc stops all motion from any window, a dialog included")
        view = self.menuBar().addMenu("&View")
        self.tab_actions: list[QAction] = []
        for i, (tabs, index, name) in enumerate(
                (("left", 0, "Protocol"), ("left", 1, "Manual control"),
                 ("left", 2, "Instruments"), ("right", 0, "Run plots"),
                 ("right", 1, "Manual (live) plot"), ("right", 2, "Live fit"),
                 ("right", 3, "Results (runs found and compared)"),
                 ("left", 3, "Queue"))):
            action = view.addAction(name)
            action.setShortcut(QKeySequence(f"Ctrl+{i + 1}"))
            action.triggered.connect(partial(self.show_tab, tabs, index))
            self.tab_actions.append(action)
        look = view.addMenu("&Appearance")
        self.appearance_actions: dict[str, QAction] = {}
        group = QActionGroup(self)
        group.setExclusive(True)
        for key, text in theme.CHOICES:
            action = look.addAction(text)
            action.setCheckable(True)
            action.setToolTip({"system": "light or dark as the system says"}.get(key, text))
            action.triggered.connect(partial(self.set_appearance, key))
            group.addAction(action)
            self.appearance_actions[key] = action
        help_menu = self.menuBar().addMenu("&Help")
        help_menu.addAction("&About gelrig", self.about)

    def set_appearance(self, choice: str) -> None:
        """Light, dark, or as the system says (View > Appearance; remembered)."""
        self.appearance = choice
        self.appearance_actions[choice].setChecked(True)
        theme.apply(theme.is_dark(choice, theme.system_dark()), self)

    def _system_scheme_changed(self, _scheme: object = None) -> None:
        if self.appearance == "system":
            self.set_appearance("system")

    def show_tab(self, side: str, index: int) -> None:
        """View menu: bring a tab forward (Ctrl+1..8)."""
        (self.left_tabs if side == "left" else self.plot_tabs).setCurrentIndex(index)

    def _on_plot_tab(self, index: int) -> None:
        """The Results tab lists the runs as they are now each time it is brought forward."""
        if self.plot_tabs.widget(index) is self.results_tab:
            self.results.refresh()

    def home_stage(self) -> None:
        """Rig menu (Ctrl+H): the manual panel's Home, when there is one and it is enabled."""
        button = self.manual.buttons.get("home")
        if button is not None and button.isEnabled():
            button.click()

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
        self.pace_box.setToolTip("how fast simulated time runs (lab time per wall time); "
                                 "hardware runs in real time")
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
        self.left_tabs.addTab(_scrolled(self.queue), "Queue")
        self.plot_tabs = QTabWidget()
        self.plot_tabs.addTab(self.plot_stack, "Run")
        self.plot_tabs.addTab(self.idle_plots, "Manual (live)")
        self.plot_tabs.addTab(self.fit_panel, "Live fit")
        self.results_tab = self.results  # not scrolled: its table and plots shrink
        self.plot_tabs.addTab(self.results_tab, "Results")
        self.plot_tabs.currentChanged.connect(self._on_plot_tab)
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(self.plot_tabs)
        right.addWidget(self.log)
        right.setStretchFactor(0, 1)
        right.setSizes([700, 160])
        self.right_split = right
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
        # elided at the window's width (the banner has the whole line): a long line cut
        # mid-word at the screen's edge read as a different statement (the walk of issue 25)
        self.safety_label = StatusLine("the interlocks' state, as on the banner")
        self.safety_label.setObjectName("safetyStatus")
        self.statusBar().addPermanentWidget(self.safety_label, 1)
        self.statusBar().showMessage("starting")

    def _wire(self) -> None:
        s = self.desk
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
        s.unloaded.connect(self._after_unload)
        self.banner.bind(s, self.log.add)
        s.safety_changed.connect(self._on_safety)
        s.stop_verified.connect(self._on_stop_verified)
        s.pending_done.connect(self._on_pending_done)
        self.instruments.connect_clicked.connect(self.connect_rig)
        self.instruments.disconnect_clicked.connect(self.disconnect_rig)
        self.manual.command.connect(self._on_manual)
        self.protocol.open_clicked.connect(self.choose_protocol)
        self.protocol.run_clicked.connect(self.run_protocol)
        self.protocol.pause_clicked.connect(self.pause)
        self.protocol.resume_clicked.connect(self.resume)
        self.protocol.abort_clicked.connect(self.abort)
        self.protocol.modified_changed.connect(lambda _m: self._update_title())
        self.protocol.form.changed.connect(self._update_title)
        self.stop_button.clicked.connect(self.stop)
        self.report_button.clicked.connect(self.open_report)
        self.pace_box.currentIndexChanged.connect(self._on_pace)

    @property
    def plots(self) -> LivePlots:
        widget = self.plot_stack.currentWidget()
        assert isinstance(widget, LivePlots)
        return widget

    # ---- remembered between sessions (QSettings) ----------------------------------------
    def _restore_settings(self) -> None:
        """The last size and place (kept within the screen), splitter sizes, recent
        protocols."""
        store = settings()
        geometry = store.value("window/geometry")
        if isinstance(geometry, QByteArray | bytes) and self.restoreGeometry(geometry):
            screen = self.screen() or QApplication.primaryScreen()
            area = screen.availableGeometry() if screen is not None else None
            if area is not None and not area.contains(self.frameGeometry()):
                fit_to_screen(self)  # saved on a larger screen: fit this one
        for key, split in (("window/main_split", self.main_split),
                           ("window/right_split", self.right_split)):
            state = store.value(key)
            if isinstance(state, QByteArray | bytes):
                split.restoreState(state)
        look = store.value("view/appearance", "system")
        self.set_appearance(look if look in self.appearance_actions else "system")
        me = weakref.ref(self)  # the application's hints outlive the window: held weakly

        def scheme_changed(_scheme: object) -> None:
            window = me()
            if window is not None:
                window._system_scheme_changed()

        self._scheme_link: QMetaObject.Connection | None = (
            QGuiApplication.styleHints().colorSchemeChanged.connect(scheme_changed))
        self.protocol.sample_form.set_texts(load_texts(store))
        self.protocol.info_form.set_texts(load_info(store))
        recent = store.value("recent/protocols") or []
        self.recent = [str(p) for p in (recent if isinstance(recent, list) else [recent])]
        self._fill_recent()

    def _save_settings(self) -> None:
        store = settings()
        store.setValue("window/geometry", self.saveGeometry())
        store.setValue("window/main_split", self.main_split.saveState())
        store.setValue("window/right_split", self.right_split.saveState())
        store.setValue("recent/protocols", self.recent)
        store.setValue("view/appearance", self.appearance)
        save_texts(store, self.protocol.sample_form.all_texts())
        save_info(store, self.protocol.info_form.texts())
        store.sync()

    def remember_sample(self) -> None:
        """Keep the Sample fields (per rig kind) and the run record (operator, note, tags)
        for the next run and window, as a run starts."""
        store = settings()
        save_texts(store, self.protocol.sample_form.all_texts())
        save_info(store, self.protocol.info_form.texts())
        store.sync()

    def remember_protocol(self, path: Path) -> None:
        """Put ``path`` first among the recent protocols (File > Recent protocols)."""
        text = str(path.resolve())
        self.recent = [text, *(p for p in self.recent if p != text)][:RECENT]
        self._fill_recent()

    def _fill_recent(self) -> None:
        self.recent_menu.clear()
        for text in self.recent:
            self.recent_menu.addAction(text, partial(self._open_recent, Path(text)))
        self.recent_menu.setEnabled(bool(self.recent))

    def _open_recent(self, path: Path) -> None:
        if not path.exists():
            self.message("Recent protocols", f"{path}: no such file any more")
            return
        self.protocol.load_file(path)
        self.remember_protocol(path)

    # ---- rig ----------------------------------------------------------------------------
    def start(self) -> None:
        """Load the rig file from the services and connect."""
        self.open_rig(self.services.rig_file)

    def open_rig(self, path: Path) -> None:
        if self.desk.running:
            self.message("Open rig", "finish or abort the run first")
            return
        self.desk.disconnect_rig()
        try:
            spec = self.desk.load_rig(path)
        except GelrigError as exc:
            self.log.add(str(exc), "error")
            self.message("Rig file", str(exc))
            return
        self.instruments.set_spec(spec)
        self.instruments.set_state("connecting…")
        self.instruments.set_connected(False, busy=True)
        self.statusBar().showMessage("connecting…")
        self.plot_stack.setCurrentWidget(self.shear_plots if spec.kind == "shear"
                                         else self.compression_plots)
        self.idle_plots.set_kind(spec.kind)
        self._update_title()
        self.pace_box.setEnabled(spec.simulated)
        self.protocol.set_pace(self.desk.pace, real_time=not spec.simulated)
        self.protocol.set_rig(spec.kind, spec.limits, connected=False,
                              rehearse=self._rehearser(spec))
        self.log.add(f"rig {spec.name} ({spec.source}), "
                     f"{'simulated' if spec.simulated else 'hardware'}: connecting")
        self.desk.connect_rig()

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
        self.desk.connect_rig()

    def disconnect_rig(self) -> None:
        self.ask_if_loaded("Disconnect", self._disconnect)

    def _disconnect(self) -> None:
        self.instruments.set_state("disconnecting…")
        self.instruments.set_connected(True, busy=True)
        self.desk.disconnect_rig()

    def _on_connected(self, rig: Rig) -> None:
        self.instruments.set_rig(rig)
        self.instruments.set_state(f"connected ({self.desk.clock_spec()} clock)")
        self.instruments.set_connected(True)
        self.manual.set_kind(rig.kind)
        desk = weakref.ref(self.desk)  # weakly: no cycle through a Qt object's attribute
        self.manual.first_touch_known = lambda: getattr(getattr(desk(), "rig", None),
                                                        "first_touch", None) is not None
        self.manual.set_enabled(True)
        self.protocol.set_rig(rig.kind, rig.limits, connected=True,
                              rehearse=self._rehearser(self.desk.spec))
        self.statusBar().showMessage("connected")
        self.log.add(f"connected: {', '.join(rig.identities)}")
        self._update_title()

    def _on_disconnected(self) -> None:
        self.instruments.set_rig(None)
        self.instruments.set_state("disconnected")
        self.instruments.set_connected(False)
        self.manual.set_enabled(False)
        spec = self.desk.spec
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
        self.idle_plots.add(values)
        self.manual.show_readings(values)
        self._last_read_error = ""

    def _on_safety(self, safety: Safety) -> None:
        """Every view renders the one safety state (the banner binds to it itself)."""
        self.header.show_safety(safety)
        self.instruments.show_safety(safety)
        self.safety_label.set_line(safety.status_line())
        self.safety_label.setStyleSheet("" if safety.state == "armed" else
                                        "color:#b00020; font-weight:bold;")
        said = safety.why_not_monitoring()
        if said and said.split(" silent for")[0] != self._said_silent:
            self.log.add(f"NOT MONITORING: {said}", "error")  # once per silence
        self._said_silent = said.split(" silent for")[0] if said else ""

    def _on_stop_verified(self, safe: SafeState) -> None:
        self.log.add(f"STOP: {safe.line()}", "info" if safe.verified else "error")

    def _on_pending_done(self, safe: SafeState | None) -> None:
        if safe is None:
            self.log.add(self.desk.pending_text, "error")
            self.message("Safe stop not completed", self.desk.pending_text)
        else:
            self.log.add(f"SAFE STOP COMPLETED LATER: {safe.line()}", "warning")

    def _on_readings_failed(self, message: str) -> None:
        if message != self._last_read_error:
            self._last_read_error = message
            self.log.add(f"readout: {message}", "warning")

    def _on_pace(self, index: int) -> None:
        rate = float(self.pace_box.itemData(index))
        self.desk.set_pace(rate)
        self.protocol.set_pace(rate, real_time=not self.pace_box.isEnabled())
        self.log.add(f"pace of simulated time: {self.pace_box.itemText(index)}")

    # ---- manual control -----------------------------------------------------------------
    def _on_manual(self, what: str, command: Command) -> None:
        if self.desk.command(what, command):
            self.log.add(what)
            self.plot_tabs.setCurrentWidget(self.idle_plots)

    def _on_motion_ended(self, result: Guarded) -> None:
        line = result.safe.line() if result.safe is not None else "the stop was not read back"
        if result.outcome == "tripped":
            self.log.add(f"{result.what}: TRIPPED {result.reason}; {line}", "error")
            self.statusBar().showMessage("interlock tripped: unload, then Acknowledge on the "
                                         "banner")
            self.message("Interlock tripped", f"{result.what}: {result.reason}\n\n{line}\n\n"
                         "Unload the sample, then Acknowledge on the banner.")
        elif result.outcome == "stopped":
            self.log.add(f"{result.what} stopped ({result.reason}): {line}",
                         "info" if result.safe is not None and result.safe.verified
                         else "error")

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

    def ask_if_loaded(self, action: str, then: Callable[[], object]) -> None:
        """Before a run or a disconnect: ``then()`` at once, or, with the sample loaded, once
        the (non-modal) question is answered yes."""
        if not self.desk.loaded:
            then()
            return
        dialogs.ask(self, "The sample is loaded",
                    f"The sample is loaded ({self.desk.loaded}). {action} all the same?\n"
                    "(Unload to the safe position is on the interlock banner.)",
                    lambda key: then() if key == "yes" else None)

    def _on_command_failed(self, what: str, message: str) -> None:
        """One line in the log; the dialog says only what is known (the verified stop's
        line follows in the log and on the banner when it is read back)."""
        self.log.add(f"{what} failed: {message}", "error")
        self.message(f"{what} failed", message)

    def stop(self) -> None:
        """Stop everything now (abort a run; else stop every axis)."""
        self.log.add("STOP: stopping all motion", "warning")
        self.desk.stop()

    # ---- protocol and run ---------------------------------------------------------------
    def choose_protocol(self) -> QFileDialog:
        start = str(self.services.protocol_dir or Path.cwd())
        return dialogs.choose(self, "Open protocol", start, self._open_protocol,
                              "Protocols and scripts (*.toml *.py);;Protocol files (*.toml);;"
                              "Protocol scripts (*.py)")

    def _open_protocol(self, path: str) -> None:
        self.protocol.load_file(Path(path))
        self.remember_protocol(Path(path))

    def save_protocol(self) -> Path | None:
        """Write the edited protocol to its file (Save as when it has none)."""
        if self.protocol.path is None:
            self.save_protocol_as()
            return None
        return self._save_to(self.protocol.path)

    def save_protocol_as(self) -> QFileDialog:
        start = self.protocol.path or (self.services.protocol_dir or Path.cwd()) / "protocol.toml"
        return dialogs.choose(self, "Save protocol as", str(start),
                              lambda path: self._save_to(Path(path)), "Protocol files (*.toml)",
                              save=True)

    def _save_to(self, path: Path) -> Path | None:
        if not self.protocol.form.table:
            self.message("Save protocol", "no protocol to save: open one first")
            return None
        try:
            saved = self.protocol.save(path)
        except OSError as exc:
            self.message("Save protocol", f"{path}: {exc.strerror or exc}")
            return None
        self.log.add(f"protocol saved to {saved}")
        return saved

    def choose_rig(self) -> QFileDialog:
        start = str(self.services.rig_dir or Path.cwd())
        return dialogs.choose(self, "Open rig file", start,
                              lambda path: self.open_rig(Path(path)), "Rig files (*.toml)")

    def runs_dir(self) -> Path:
        """Where runs are recorded (``--runs``): Open run starts there."""
        folder = self.services.runs_dir or Path("runs")
        return folder if folder.is_dir() else Path.cwd()

    def choose_run(self) -> QFileDialog:
        return dialogs.choose(self, "Open a finished run", str(self.runs_dir()),
                              lambda path: self.open_run(Path(path)), folder=True)

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
        if self.protocol.refusal and not self.protocol.why_not and not self.desk.running:
            self.refuse_run(self.protocol.refusal, "made")  # nothing to move: no question
            return
        spec = self.protocol.spec
        if spec is None or self.protocol.why_not:
            return
        self.ask_if_loaded("Start the run", self._start_run)

    def _start_run(self) -> None:
        spec = self.protocol.spec
        if spec is None or self.protocol.why_not or self.desk.running:
            return
        self.remember_sample()
        try:
            path = self.desk.start_run(spec, self.protocol.info_form.info)
        except Refused as exc:  # nothing moved, nothing made (ADR 0330)
            self.refuse_run(str(exc), "made")
            return
        except (GelrigError, OSError) as exc:
            self.log.add(f"cannot start the run: {exc}", "error")
            self.message("Cannot start the run", str(exc))
            return
        self.log.add(f"run of {spec.name!r} started; recording to {path}")

    def start_queued(self, procedure: Procedure, info: RunInfo) -> str:
        """The queue's run, started as Run starts one (the same desk and run host); '' or
        the one line why it did not start."""
        if self.desk.running:
            return "a run is already going"
        try:
            path = self.desk.start_run(procedure, info)
        except Refused as exc:  # nothing moved, nothing made (ADR 0330)
            self.refuse_run(str(exc), "made")
            return str(exc)
        except (GelrigError, OSError) as exc:
            self.log.add(f"cannot start the queued run: {exc}", "error")
            return str(exc)
        limits = self.desk.spec.limits if self.desk.spec is not None else None
        if isinstance(procedure, ProtocolSpec) and limits is not None:  # progress and ETA
            self.protocol.run_plan = dry_run(procedure, limits)
        self.log.add(f"queued run of {procedure.name!r} started; recording to {path}")
        return ""

    def _queue_item(self) -> QueueItem | str:
        """The Protocol tab's file or script as a queue item (with its script parameters,
        the Sample fields and the run record), or why it cannot be queued."""
        panel = self.protocol
        if panel.path is None:
            return "open a protocol file or script first: the queue runs files"
        if panel.modified:
            return "save the protocol first: the queue runs the file as saved"
        if panel.errors or panel.info_form.info is None:
            return "fix the fields first: " + "; ".join(panel.errors + panel.info_form.errors)
        info = panel.info_form.info
        params = {name: entry.text() for name, entry in panel.script_form.entries.items()
                  if entry.text().strip()} if panel.is_script else {}
        return QueueItem(str(panel.path), params, panel.sample_form.table(), info.operator,
                         info.note, list(info.tags))

    def refuse_run(self, line: str, folder: str) -> None:
        """A run refused before anything moved: its one line in the log, the status bar and
        a message (no run folder was ``folder``: made, or kept)."""
        self.statusBar().showMessage(f"run refused: {line}")
        self.log.add(f"run refused: {line}; no run folder {folder}", "error")
        self.message("Run refused", f"{line}\n\nNothing moved; no run folder was {folder}.")

    def pause(self) -> None:
        """Pause at the next checkpoint; during a hold, offer to end it or abort instead."""
        if self.desk.holding:
            self.protocol.ask_hold(self._on_hold_choice)
            return
        self.desk.pause()
        self.protocol.request_pause()
        self.log.add("pause requested (takes effect at the next checkpoint)")

    def _on_hold_choice(self, choice: str) -> None:
        """The (non-modal) pause-in-hold question answered: end the hold, or abort."""
        if choice == "end":
            if self.desk.end_hold():
                self.protocol.hold_ending()
                self.log.add("ending the hold now (its data is kept; the run goes on)")
            else:
                self.log.add("the hold had already ended")
        elif choice == "abort" and self.desk.running:
            self.abort()

    def resume(self) -> None:
        self.desk.resume()
        self.protocol.cancel_pause()
        self.log.add("resume")

    def abort(self) -> None:
        self.desk.abort("aborted from the GUI")
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
        if not self.queue_runner.active:  # a queue's runs: the Queue tab stays in view
            self.left_tabs.setCurrentIndex(0)
        self.manual.set_enabled(False)
        self.instruments.set_connected(True, busy=True)
        self.protocol.set_state(RunState.RUNNING)
        self.statusBar().showMessage(f"running; recording to {path}")

    def _on_run_finished(self, state: RunState, reason: str) -> None:
        self.plots.refresh(self.desk.data)
        release()  # what the runner and recorder held during the run
        words = in_words(reason)  # the raw reason goes to the log pane below
        self.protocol.set_state(state, words)
        connected = self.desk.rig is not None
        self.manual.set_enabled(connected)
        self.instruments.set_connected(connected)
        if self.desk.run_path is None:  # refused before anything moved: its folder is gone
            self.shown_run = None
            self.refuse_run(reason, "kept")
        else:
            self.statusBar().showMessage(f"run {state.value}: {words}; data in "
                                         f"{self.desk.run_path}")
            self.log.add(f"run {state.value}: {reason}; data kept in {self.desk.run_path}")
        analyze = self.services.analyze is not None and self.desk.run_path is not None
        self.report_button.setVisible(analyze)
        self.report_action.setEnabled(analyze)
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
        if not self.desk.running:
            return
        progress = self.desk.take_progress()
        if progress is not None:
            self.protocol.show_progress(progress, self._step_names.get(progress.index, ""))
        now = time.perf_counter()
        if now < self._next_draw:
            return
        if self.plots.refresh(self.desk.data):
            self.plots.paint_now()
            cost = time.perf_counter() - now
            self._next_draw = now + cost / REDRAW_SHARE

    # ---- title, export, report, about ---------------------------------------------------
    def _update_title(self) -> None:
        """'gelrig — <rig> (simulated) — run <dir> (running)'."""
        parts = ["gelrig"]
        spec = self.desk.spec
        if spec is not None:
            parts.append(f"{spec.name} ({'simulated' if spec.simulated else 'hardware'})")
        if self.shown_run is not None:
            state = "running" if self.desk.running else self.desk.state.value
            parts.append(f"run {self.shown_run.name} ({state})")
        if self.protocol.form.table:
            name = self.protocol.path.name if self.protocol.path else "protocol"
            parts.append(f"{name}{' *' if self.protocol.modified else ''}")
        self.setWindowTitle(" — ".join(parts))

    def export_png(self, path: Path | None = None) -> Path | None:
        """The plots on show as a PNG (asks where unless ``path`` is given)."""
        widget = self.plot_tabs.currentWidget()
        if path is None:
            dialogs.choose(self, "Export plot as PNG", str(self._export_start("plot.png")),
                           lambda chosen: self.export_png(Path(chosen)), "PNG images (*.png)",
                           save=True)
            return None
        if not widget.grab().save(str(path), "PNG"):
            self.message("Export plot", f"{path}: could not write the image")
            return None
        self.log.add(f"plot exported to {path}")
        return path

    def export_csv(self, path: Path | None = None) -> Path | None:
        """The run's samples (the columns the plots use, one row per sample with its step
        index) as CSV; the full record stays in the run directory's HDF5 files."""
        data = self.desk.data
        if not data.samples():
            self.message("Export data", "no run data to export yet: run a protocol first")
            return None
        if path is None:
            dialogs.choose(self, "Export data as CSV", str(self._export_start("data.csv")),
                           lambda chosen: self.export_csv(Path(chosen)), "CSV files (*.csv)",
                           save=True)
            return None
        try:
            rows = export.write_csv(data, path)
        except OSError as exc:
            self.message("Export data", f"{path}: {exc.strerror or exc}")
            return None
        self.log.add(f"{rows} samples exported to {path}")
        return path

    def _export_start(self, name: str) -> Path:
        run = self.desk.run_path
        return (run / name) if run is not None else self.runs_dir() / name

    def open_report(self) -> None:
        """The last run's HTML report in the browser (analysing the run first if needed)."""
        run, analyze = self.desk.run_path, self.services.analyze
        if run is None or analyze is None:
            self.message("Open report", "no finished run to report on")
            return
        report = run / "analysis" / "report.html"
        if report.exists():
            self._show_report(report)
            return
        self.log.add(f"analysing {run} for its report…")
        self.report_button.setEnabled(False)

        def work() -> Path:
            analyze(run)  # an exception is handed to _report_ready, shown, not raised
            return report

        offthread.start(work, self._report_ready, name="gelrig-report")

    def _report_ready(self, result: object) -> None:
        self.report_button.setEnabled(True)
        if isinstance(result, Path) and result.exists():
            self._show_report(result)
        else:
            self.log.add(f"no report: {result}", "error")
            self.message("Open report", f"the analysis wrote no report: {result}")

    def _show_report(self, report: Path) -> bool:
        """Open the report in the browser; when none opens, say where the file is."""
        self.log.add(f"report: {report}")
        if QDesktopServices.openUrl(QUrl.fromLocalFile(str(report.resolve()))):
            return True
        self.message("Open report", f"No browser opened. The report is at:\n{report.resolve()}")
        self.log.add(f"no browser opened; the report is at {report.resolve()}", "warning")
        return False

    def about(self) -> QMessageBox:
        return dialogs.inform(self, "About gelrig",
                       "<b>gelrig</b>: contact mechanics of soft spheres — the plate-"
                          "compression rig (KDC101 stage, USB-6001 DAQ) and the MCR 501 shear "
                          "rig, their simulators, protocols in virtual time, analysis.<br><br>"
                       "STOP or Esc stops all motion at any time.",
                       QMessageBox.Icon.Information)

    def message(self, title: str, text: str) -> QMessageBox:
        """A clear, non-blocking message box (the GUI keeps running behind it)."""
        box = dialogs.inform(self, title, text)
        self.last_message = box
        self._watch_box(box)
        return box

    # ---- closing ------------------------------------------------------------------------
    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt override)
        """Mid-run: ask, then abort (motion stops), keep the data, close when the run ended.
        With the sample loaded: ask to unload and close, close leaving it loaded, or cancel.
        Every question is non-modal: STOP stays in reach."""
        if self.desk.running:
            event.ignore()
            if not self.close_after_run:
                self._ask_close("A run is in progress",
                                "A protocol is running. Abort it (all motion stops at once) "
                                "and close?\nThe data recorded so far is kept.",
                                dialogs.YES_NO, self._on_close_mid_run)
            return
        if self.desk.loaded and not self._leave_loaded and not self.desk.wedged:
            event.ignore()
            self._ask_close("The sample is loaded",
                            f"The sample is loaded ({self.desk.loaded}).\n\nUnload it to "
                            "the rig's safe position and close, close leaving it loaded, or "
                            "cancel?", CLOSE_LOADED, self._on_close_loaded, default="cancel")
            return
        self._timer.stop()
        self._escape.remove()
        link, self._scheme_link = self._scheme_link, None
        if link is not None:  # once (a close may come twice)
            QGuiApplication.styleHints().colorSchemeChanged.disconnect(link)
        self._save_settings()
        self.queue_runner.stop()  # a queued rehearsal abandoned: its item waits again
        self.protocol.cancel_rehearsal()
        logging.getLogger().removeHandler(self._log_handler)
        if self._file_log is not None:
            logging.getLogger().removeHandler(self._file_log[0])
            self._file_log[0].close()
        self.desk.shutdown()
        for window in list(self.run_windows):
            window.close()
        event.accept()

    def _ask_close(self, title: str, text: str, choices: tuple[dialogs.Choice, ...],
                   then: Callable[[str], object], default: str = "no") -> None:
        """One closing question at a time (a second close raises it)."""
        box = self._close_box
        if box is not None and box.isVisible():
            box.raise_()
            return
        box = dialogs.ask(self, title, text, then, choices, default)
        if isinstance(box, QMessageBox):  # (a test may answer at once, with no box)
            self._close_box = box
            self._watch_box(box)

    def _watch_box(self, box: QMessageBox) -> None:
        """Forget ``box`` once it is closed (the window held weakly: no cycle through Qt)."""
        me = weakref.ref(self)

        def closed(_result: int) -> None:
            window = me()
            if window is not None:
                window._forget_box(box)

        box.finished.connect(closed)

    def _forget_box(self, box: QMessageBox) -> None:
        """A closed box is deleted (WA_DeleteOnClose): hold no reference to it."""
        if self._close_box is box:
            self._close_box = None
        if self.last_message is box:
            self.last_message = None

    def _on_close_mid_run(self, key: str) -> None:
        if key != "yes" or not self.desk.running:
            return
        self.close_after_run = True
        self.desk.close_requested()
        self.log.add("aborting the run before closing", "warning")

    def _on_close_loaded(self, key: str) -> None:
        if key == "leave":
            self._leave_loaded = True
            self.log.add(f"closing with the sample loaded ({self.desk.loaded})", "warning")
            self.close()
        elif key == "unload" and self.desk.unload():
            self._close_after_unload = True
            self.log.add("unloading the sample before closing")

    def _after_unload(self, safe: SafeState) -> None:
        """Unload and close: close once the unload is verified; else say what is known."""
        if not self._close_after_unload:
            return
        self._close_after_unload = False
        if safe.verified:
            self._leave_loaded = True  # unloaded (verified): nothing left to ask
            self.close()
        else:
            self.message("Unload not verified: the window stays open", safe.line())


#: The choices when closing with the sample loaded.
CLOSE_LOADED: tuple[dialogs.Choice, ...] = (
    ("unload", "Unload and close", QMessageBox.ButtonRole.AcceptRole),
    ("leave", "Close leaving it loaded", QMessageBox.ButtonRole.DestructiveRole),
    ("cancel", "Cancel", QMessageBox.ButtonRole.RejectRole))


def _scrolled(widget: QWidget) -> QScrollArea:
    """``widget`` in a scroll area that lets it shrink (a small window scrolls it)."""
    scroll = QScrollArea()
    scroll.setWidgetResizable(True)
    scroll.setWidget(widget)
    scroll.setMinimumSize(0, 0)
    return scroll
