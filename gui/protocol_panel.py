"""Protocol panel: open a protocol file, edit it (validated as you type), see the dry run,
run / pause / resume / abort, and follow the progress with a lab-time ETA."""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
import threading
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QFontDatabase, QResizeEvent
from PySide6.QtWidgets import (
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from gelrig.gui import dialogs, offthread
from gelrig.gui.protocol_form import ProtocolForm
from gelrig.gui.run_info_form import RunInfoForm
from gelrig.gui.sample_form import SampleForm
from gelrig.gui.script_form import ScriptForm
from gelrig.gui.tomlout import dumps
from gelrig.instrument.core.units import lab_time
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import Progress, RunState
from gelrig.protocols.plan import PlanSummary, dry_run
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rehearsal import RehearsalReport, human_bytes
from gelrig.protocols.rig import CompressionLimits, ShearLimits
from gelrig.protocols.script import Script, load_script
from gelrig.protocols.spec import ProtocolSpec

log = logging.getLogger(__name__)

Rehearse = Callable[[Procedure, RunControl], RehearsalReport]
#: Quiet time (ms) after the last edit before a rehearsal starts.
REHEARSAL_DELAY_MS = 400


def eta(plan: PlanSummary, progress: Progress) -> tuple[float, float]:
    """(overall fraction done, lab seconds left) from the plan and the newest progress."""
    durations = plan.durations
    i = min(progress.index, len(durations) - 1)
    step = durations[i]
    left = progress.remaining if progress.remaining > 0 else step * (1 - progress.fraction)
    left += sum(durations[i + 1:])
    total = plan.total
    done = sum(durations[:i]) + progress.fraction * step
    return (done / total if total > 0 else 0.0), left


#: The choices of Pause during a hold.
HOLD_CHOICES: tuple[dialogs.Choice, ...] = (
    ("end", "End the hold now", QMessageBox.ButtonRole.AcceptRole),
    ("abort", "Abort", QMessageBox.ButtonRole.DestructiveRole),
    ("cancel", "Cancel", QMessageBox.ButtonRole.RejectRole))


class PathLabel(QLabel):
    """The protocol's file: elided in the middle at the width it is given (a long path never
    widens the panel past its tab), the whole of it in ``text()`` and the tooltip."""

    def __init__(self, text: str = "", parent: QWidget | None = None):
        super().__init__(parent)
        self.full = ""
        self.setMinimumWidth(0)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setText(text)

    def setText(self, text: str) -> None:  # noqa: N802 (Qt's name)
        self.full = text
        self.setToolTip(text)
        self._elide()

    def text(self) -> str:
        return self.full

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        self._elide()

    def _elide(self) -> None:
        super().setText(self.fontMetrics().elidedText(self.full, Qt.TextElideMode.ElideMiddle,
                                                      max(self.width(), 1)))


class ProtocolPanel(QGroupBox):
    """The protocol to run and the controls of its run."""

    open_clicked = Signal()
    run_clicked = Signal()
    modified_changed = Signal(bool)  # differs from its file, or saved, or another file read
    pause_clicked = Signal()
    resume_clicked = Signal()
    abort_clicked = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Protocol", parent)
        layout = QVBoxLayout(self)
        top = QHBoxLayout()
        self.open_button = QPushButton("Open protocol…")
        self.open_button.setToolTip("read a protocol file (TOML) into the form (Ctrl+O)")
        self.open_button.clicked.connect(self.open_clicked)
        self.file_label = PathLabel("no protocol")
        top.addWidget(self.open_button)
        top.addWidget(self.file_label, 1)
        layout.addLayout(top)
        self.form = ProtocolForm()
        self.form.changed.connect(self._update)
        self.form.changed.connect(self._check_modified)
        #: the protocol file shown (None: not from a file, or not saved yet)
        self.path: Path | None = None
        self._saved: dict[str, Any] = {}  # the table as last read or written
        self.modified = False
        self.script_form = ScriptForm()
        self.script_form.changed.connect(self._update)
        #: the form shown: the protocol file's steps, or a script's parameters
        self.forms = QStackedWidget()
        self.forms.addWidget(self.form)
        self.forms.addWidget(self.script_form)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.forms)
        layout.addWidget(scroll, 3)
        self.plan_text = QPlainTextEdit()
        self.plan_text.setReadOnly(True)
        self.plan_text.setFont(QFontDatabase.systemFont(QFontDatabase.SystemFont.FixedFont))
        self.plan_text.setPlaceholderText("dry run: steps, lab duration, limit checks")
        layout.addWidget(QLabel("<b>Dry run</b>"))
        layout.addWidget(self.plan_text, 2)
        #: the run's sample: replaces the file's [sample]; Save writes it
        self.sample_form = SampleForm()
        self.sample_form.changed.connect(self._sample_changed)
        layout.addWidget(self.sample_form)
        #: who runs it and why (operator, note, tags): recorded in run.json
        self.info_form = RunInfoForm()
        self.info_form.changed.connect(self._update)
        layout.addWidget(self.info_form)
        buttons = QHBoxLayout()
        self.run_button = QPushButton("Run")
        self.run_button.setToolTip("run the protocol on the connected rig, recording to a new "
                                   "run directory (Ctrl+R)")
        self.pause_button = QPushButton("Pause")
        self.pause_button.setToolTip("pause at the next checkpoint, where nothing moves; "
                                     "during a hold: end it or abort (Ctrl+P)")
        self.resume_button = QPushButton("Resume")
        self.resume_button.setToolTip("go on after a pause")
        self.abort_button = QPushButton("Abort")
        self.abort_button.setToolTip("end the run now: motion stops, the sample is made safe, "
                                     "the data is kept")
        for button, signal in ((self.run_button, self.run_clicked),
                               (self.pause_button, self.pause_clicked),
                               (self.resume_button, self.resume_clicked),
                               (self.abort_button, self.abort_clicked)):
            button.clicked.connect(signal)
            buttons.addWidget(button)
        layout.addLayout(buttons)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.progress.setFormat("%p %")
        self.status = QLabel("idle")
        self.status.setWordWrap(True)
        layout.addWidget(self.progress)
        layout.addWidget(self.status)
        self.kind: str | None = None
        self.limits: CompressionLimits | ShearLimits | None = None
        self.connected = False
        self.pace = 1.0
        self.real_time = False
        self.state = RunState.IDLE
        self.pause_requested = False
        self.plan: PlanSummary | None = None
        #: the plan of a run not started from the form (a queued one): its progress and ETA
        self.run_plan: PlanSummary | None = None
        self.rehearse_fn: Rehearse | None = None
        self.rehearsal: RehearsalReport | None = None
        self.rehearsal_error = ""
        self._rehearsing: Procedure | None = None  # the spec a rehearsal runs or ran for
        self._rehearsal_control: RunControl | None = None
        self._rehearsal_timer = QTimer(self)
        self._rehearsal_timer.setSingleShot(True)
        self._rehearsal_timer.timeout.connect(self._start_rehearsal)
        self._rehearsal_poll = QTimer(self)
        self._rehearsal_poll.setInterval(150)
        self._rehearsal_poll.timeout.connect(self._collect_rehearsal)
        self._outbox: list[tuple[Procedure, object]] = []
        self.why_not = "open a protocol file"
        self._update()

    # ---- inputs -------------------------------------------------------------------------
    @property
    def spec(self) -> Procedure | None:
        """What Run runs: the form's protocol, or the script with its fields' values; each
        measuring the sample in the Sample fields (None while a field holds a bad value)."""
        if self.sample_form.errors:
            return None
        if not self.is_script:
            return self.form.spec
        script, base = self.script_form.script, self.script_form.base
        if script is None:
            return None
        sample = self.sample_form.sample or (base.sample if base is not None else None)
        if script.sample != sample:  # one Script per sample: its rehearsal is kept
            self.script_form.script = script = dataclasses.replace(script, sample=sample)
        return script

    @property
    def refusal(self) -> str:
        """The one line a run of this protocol is refused with before anything moves (a
        size of the sample that nobody gave, as ``gelrig run`` says it); '' if none."""
        if self.is_script or self.sample_form.errors or self.form.missing is None:
            return ""
        return str(self.form.missing)

    def _sample_changed(self) -> None:
        """The Sample fields changed: the protocol is read again with them."""
        if self.is_script:
            self._update()
            return
        self.form.sample_table = self.sample_form.table()
        if self.form.table:
            self.form.validate()  # emits changed: the plan, the modified mark
        else:
            self._update()

    @property
    def is_script(self) -> bool:
        return self.forms.currentWidget() is self.script_form

    @property
    def errors(self) -> list[str]:
        own = self.script_form.errors if self.is_script else self.form.errors
        return self.sample_form.errors + own

    def load_file(self, path: Path) -> None:
        """Read a protocol file into the form (TOML errors shown as the form's message), or
        a script (``.py``) into the script's parameter fields."""
        if path.suffix == ".py":
            self.load_script(path)
            return
        try:
            table: dict[str, Any] = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as exc:
            self.form.set_table({}, str(path))
            self.form.general.setText(f"{path}: cannot be read as TOML ({exc})")
            return
        self.set_table(table, str(path))
        self.path = path
        self.modified_changed.emit(self.modified)  # the title names the file now

    def load_script(self, path: Path) -> None:
        """A protocol script: its parameters as fields; Run and the rehearsal run it."""
        self.forms.setCurrentWidget(self.script_form)
        self.form.missing = None
        self.path, self.modified = path, False
        self.file_label.setText(str(path))
        try:
            script = load_script(str(path))
        except Exception as exc:  # a script's import error is the user's: said, not raised
            self.script_form.base = None
            self.script_form.script, self.script_form.errors = None, [
                f"{path}: cannot be loaded as a script ({type(exc).__name__}: {exc})"]
            self.script_form.head.setText("")
            self.script_form.message.setText(self.script_form.errors[0])
            self._update()
        else:
            self.sample_form.set_kind(script.rig)
            if script.sample is not None:
                self.sample_form.set_table(script.sample.table())
            self.script_form.set_script(script)
        self.modified_changed.emit(self.modified)

    def set_table(self, table: dict[str, Any], source: str) -> None:
        self.forms.setCurrentWidget(self.form)
        self.path = None
        self.file_label.setText(source)
        head = table.get("protocol")
        self.form.table = {}  # the Sample fields fill without reading the old protocol again
        self.sample_form.set_kind(head.get("rig") if isinstance(head, dict) else self.kind)
        if "sample" in table:  # the file's sample, shown and editable
            self.sample_form.set_table(table["sample"])
        self.form.sample_table = self.sample_form.table()
        self.form.set_table(table, source)
        self._saved = self.form.edited_table()  # as the entries show it: the baseline
        self._check_modified()

    def _check_modified(self) -> None:
        """The modified mark: the edited protocol differs from what was read or saved."""
        if self.is_script:
            return  # a script's parameters are the run's, never written to its file
        modified = bool(self.form.table) and self.form.edited_table() != self._saved
        name = str(self.path) if self.path is not None else self.form.source
        self.file_label.setText(f"{name} (modified)" if modified else name)
        if modified != self.modified:
            self.modified = modified
            self.modified_changed.emit(modified)

    def save(self, path: Path | None = None) -> Path:
        """Write the edited protocol as TOML to ``path`` (default: its file); reading it back
        gives the same protocol. Raises OSError (said by the caller)."""
        if self.is_script:
            raise OSError("a script is edited in a text editor; the values of its parameters "
                          "are kept in the run's run.json")
        target = path or self.path
        if target is None:
            raise OSError("the protocol has no file yet: Save as")
        table = self.form.edited_table()
        target.write_text(dumps(table), encoding="utf-8")
        self._saved, self.path = copy.deepcopy(table), target
        self.form.source = str(target)
        self._check_modified()
        self.modified_changed.emit(self.modified)  # the title names the file saved to
        return target

    def set_rig(self, kind: str | None, limits: CompressionLimits | ShearLimits | None,
                connected: bool, rehearse: Rehearse | None = None) -> None:
        """The rig the protocol is planned for; ``rehearse`` runs a protocol on its twin."""
        if rehearse is not self.rehearse_fn:
            self.rehearse_fn, self._rehearsing, self.rehearsal = rehearse, None, None
        self.kind, self.limits, self.connected = kind, limits, connected
        if not self.form.table and not self.is_script:  # no protocol: the rig's sample
            self.sample_form.set_kind(kind)
        self._update()

    def set_pace(self, pace: float, real_time: bool) -> None:
        self.pace, self.real_time = pace, real_time

    def set_state(self, state: RunState, reason: str = "") -> None:
        self.state = state
        if self.active:
            self.cancel_rehearsal()
        if state != RunState.RUNNING:
            self.pause_requested = False
        if state.finished:
            self.run_plan = None
        if state == RunState.PAUSED:
            self.status.setText("paused at a checkpoint (nothing moves); Resume or Abort")
        elif state.finished:
            self.status.setText(f"run {state.value}" + (f": {reason}" if reason else ""))
            if state == RunState.COMPLETED:
                self.progress.setValue(1000)
        elif state == RunState.RUNNING and reason == "resumed":
            self.status.setText("running")
        self._update()

    def request_pause(self) -> None:
        self.pause_requested = True
        self.status.setText("pause requested: the run pauses at the next checkpoint (before "
                            "the next step; nothing moves then)")
        self._update()

    def ask_hold(self, on_choice: Callable[[str], object]) -> QMessageBox:
        """Pause pressed during a hold: ``on_choice("end")`` (end the hold now) or
        ``on_choice("abort")`` once answered (a non-modal question: STOP stays in reach).

        A hold cannot pause without changing the physics (the sample relaxes under the held
        strain whatever the software does), so the choice is to end it or abort."""
        return dialogs.ask(self, "Pause during a hold",
                           "The run is holding the sample at its strain. A hold cannot pause "
                           "without changing the physics: the sample goes on relaxing.\n\n"
                           "End the hold now: the hold's data is kept and the run goes on "
                           "with its next phase.\nAbort: the run stops and the plate "
                           "retracts.", on_choice, HOLD_CHOICES, default="cancel")

    def hold_ending(self) -> None:
        self.status.setText("ending the hold now: its data is kept, the run goes on")

    def cancel_pause(self) -> None:
        self.pause_requested = False
        self._update()

    def show_progress(self, progress: Progress, step_name: str = "") -> None:
        plan = self.run_plan or self.plan
        if plan is None:
            return
        fraction, left = eta(plan, progress)
        self.progress.setValue(round(1000 * min(max(fraction, 0.0), 1.0)))
        if self.real_time or self.pace == 1.0:  # lab time is wall time
            wall = ""
        elif math.isinf(self.pace):
            wall = " (as fast as possible)"
        else:
            wall = f" (≈ {lab_time(left / self.pace)} at {self.pace:g}x)"
        # the run's step index (as in run.json, the step files, the log and the plots)
        last = len(plan.durations) - 1
        what = f"step {progress.index}" + (f" {step_name}" if step_name else "")
        what += f" (steps 0–{last})"
        if progress.message:
            what += f": {progress.message}"
        paused = "; pause requested (before the next step)" if self.pause_requested else ""
        self.status.setText(f"{what} — ETA {lab_time(left)} lab time{wall}{paused}")

    # ---- state ------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        return self.state in (RunState.RUNNING, RunState.PAUSED, RunState.ABORTING)

    def _update(self) -> None:
        spec = self.spec
        self.plan = None
        if spec is not self._rehearsing:
            self.rehearsal, self.rehearsal_error = None, ""
        if isinstance(spec, Script):  # no steps known before it runs: its rehearsal
            self.plan_text.setPlainText(
                "a script decides its steps as it runs: its plan is the rehearsal"
                + (self._rehearsal_text(spec) if self.limits is not None else
                   "\n\nconnect a rig for the rehearsal on its twin"))
        elif isinstance(spec, ProtocolSpec) and self.limits is not None:
            self.plan = dry_run(spec, self.limits)
            self.plan_text.setPlainText(self.plan.text() + self._rehearsal_text(spec))
        elif spec is not None:
            self.plan_text.setPlainText("connect a rig for the dry run (its limits)")
        elif self.refusal:  # refused as gelrig plan and run refuse it: the one line
            self.plan_text.setPlainText(f"{self.refusal}\n\nrefused before anything moves: "
                                        "give the size in the Sample fields above Run")
        else:
            self.plan_text.setPlainText("\n".join(self.errors))
        missing = self.form.missing if self.refusal else None
        self.sample_form.set_needed({} if missing is None else {
            missing.size: f"{missing.field} takes it from the sample: give it here"})
        self.why_not = self._why_not(spec)
        self.run_button.setEnabled(not self.why_not)
        self.run_button.setToolTip(self.why_not or (
            f"refused before anything moves: {self.refusal}" if self.refusal else
            "run this protocol on the connected rig"))
        self.pause_button.setEnabled(self.state == RunState.RUNNING and not self.pause_requested)
        self.resume_button.setEnabled(self.state == RunState.PAUSED)
        self.abort_button.setEnabled(self.active)
        self.open_button.setEnabled(not self.active)
        self.forms.setEnabled(not self.active)
        self.sample_form.setEnabled(not self.active)
        self.info_form.setEnabled(not self.active)
        if not self.active and self.refusal and self.state == RunState.IDLE:
            self.status.setText(f"a run is refused: {self.refusal}")
        elif not self.active and self.why_not and self.state == RunState.IDLE:
            self.status.setText(f"not ready: {self.why_not}")
        elif not self.active and self.state == RunState.IDLE:
            self.status.setText(f"ready{self._rehearsal_status()}")

    def _why_not(self, spec: Procedure | None) -> str:
        if self.active:
            return "a run is going"
        if self.info_form.errors:
            return f"fix the run record: {self.info_form.errors[0]}"
        if spec is None and self.refusal:  # Run says it is refused (the CLI's line)
            return "" if self.connected else "connect the rig"
        if spec is None:
            return "fix the protocol: " + "; ".join(self.errors) if self.errors \
                else "open a protocol file"
        if not self.connected:
            return "connect the rig"
        if spec.rig != self.kind:
            return f"this protocol runs on a {spec.rig} rig; the rig is a {self.kind} rig"
        if self.plan is not None and self.plan.failed:
            return f"limit check failed: {self.plan.failed[0]}"
        if self.rehearsal is not None and not self.rehearsal.ok:
            return f"rehearsal failed: {self.rehearsal.failure()}"
        return ""

    # ---- the rehearsal on the rig's twin --------------------------------------------------
    def _rehearsal_status(self) -> str:
        """The rehearsal's verdict for the status line, where it is seen without scrolling."""
        if self.rehearsal is not None and self.rehearsal.ok:
            return (f": rehearsed on the rig's twin, {lab_time(self.rehearsal.total)} lab time, "
                    f"{human_bytes(self.rehearsal.bytes)} of data")
        if self.rehearse_fn is not None and self._rehearsing is self.spec and \
                self.rehearsal is None and not self.rehearsal_error:
            return " (rehearsing on the rig's twin...)"
        return ""

    def _rehearsal_text(self, spec: Procedure) -> str:
        """The rehearsal's lines under the static plan; schedules one if none ran for spec."""
        if self.rehearse_fn is None or self.active or (self.plan and self.plan.failed):
            return ""
        head = "\n\nRehearsal on the rig's twin (simulators, same limits, virtual time):\n"
        if spec is self._rehearsing and self.rehearsal is not None:
            return head + "\n".join(self.rehearsal.lines())
        if spec is self._rehearsing and self.rehearsal_error:
            return head + f"could not rehearse: {self.rehearsal_error}"
        if spec is not self._rehearsing:
            self._rehearsing = spec
            self._rehearsal_timer.start(REHEARSAL_DELAY_MS)
        return head + "rehearsing..."

    def cancel_rehearsal(self) -> None:
        """Abort a rehearsal still running (the protocol changed, a run starts, the window
        closes): it would only take time from the run."""
        self._rehearsal_poll.stop()
        self._outbox = []
        if self._rehearsal_control is not None:
            self._rehearsal_control.abort("superseded")
            self._rehearsal_control = None
            if self.rehearsal is None and not self.rehearsal_error:
                self._rehearsing = None  # unfinished: rehearse again when next asked

    def _start_rehearsal(self) -> None:
        spec, rehearse = self._rehearsing, self.rehearse_fn
        if spec is None or rehearse is None or spec is not self.spec or self.active:
            return
        self.cancel_rehearsal()
        self._rehearsing = spec
        control = self._rehearsal_control = RunControl()
        outbox: list[tuple[Procedure, object]] = []  # the thread touches no Qt object

        def work() -> None:
            try:
                result: object = rehearse(spec, control)
            except Exception as exc:  # the twin could not be built: say so, keep the GUI
                log.warning("rehearsal failed to run: %s", exc, exc_info=True)
                result = f"{type(exc).__name__}: {exc}"
            outbox.append((spec, result))

        self._outbox = outbox
        offthread.refuse_qt(work)
        threading.Thread(target=work, name="rehearsal", daemon=True).start()
        self._rehearsal_poll.start()

    def _collect_rehearsal(self) -> None:
        """On the GUI thread: take a finished rehearsal's result, if any."""
        if self._outbox:
            self._rehearsal_poll.stop()
            self._on_rehearsed(*self._outbox.pop())

    def _on_rehearsed(self, spec: object, result: object) -> None:
        if spec is not self._rehearsing:
            return  # the protocol changed meanwhile; a newer rehearsal is on its way
        if isinstance(result, RehearsalReport):
            self.rehearsal = result
        else:
            self.rehearsal_error = str(result)
        self._update()
