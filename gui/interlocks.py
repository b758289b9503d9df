"""The interlock banner: always visible and always true, rendered from the desk's one
:class:`~gelrig.gui.safety.Safety` state (so it agrees with the header, the Instruments tab,
the status bar and the dialogs). Grey "not monitoring" while no rig answers or an instrument
is silent (named, with for how long); green "armed" with the live values (and what is not
armed: the overlap limit before a contact search); red "tripped" with the verified stop
line, and an Acknowledge that re-arms once a fresh reading is within the limits. Below it,
whether the sample is loaded, with an Unload that puts it in the rig's safe position."""

from __future__ import annotations

import re
from collections.abc import Callable

from PySide6.QtWidgets import QFrame, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from gelrig.gui.desk import RigDesk
from gelrig.gui.safety import Safety
from gelrig.protocols.safestop import SafeState

_OK = "background:#d8f5d0; color:#14521a; padding:6px; border-radius:4px;"
_OFF = "background:#e0e0e0; color:#333333; padding:6px; border-radius:4px;"
_SILENT = ("background:#e0e0e0; color:#7a1f00; font-weight:bold; padding:6px; "
           "border-radius:4px; border:2px solid #c62828;")
_TRIPPED = "background:#c62828; color:white; font-weight:bold; padding:6px; border-radius:4px;"
_LOADED = "background:#fff3c4; color:#5d4200; padding:4px; border-radius:4px;"

#: live value key -> (what, SI unit), in the order shown
LIVE = (("force_N", "force", "N"), ("torque_Nm", "torque", "N*m"),
        ("normal_force_N", "normal force", "N"))


class InterlockBanner(QFrame):
    """Interlock state (``off``, ``silent``, ``armed``, ``tripped``) and the sample."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        row = QHBoxLayout()
        self.label = QLabel()
        self.label.setObjectName("bannerText")
        self.label.setWordWrap(True)
        # two lines always fit (the splitter may not squeeze the state out of sight)
        self.label.setMinimumHeight(2 * self.label.fontMetrics().lineSpacing() + 14)
        self.label.setToolTip("the interlocks' state: what is checked now, and what is not")
        self.ack_button = QPushButton("Acknowledge")
        self.ack_button.setToolTip("re-arm the interlocks (once a fresh reading is within "
                                   "the limits)")
        row.addWidget(self.label, 1)
        row.addWidget(self.ack_button)
        layout.addLayout(row)
        sample = QHBoxLayout()
        self.sample_label = QLabel()
        self.sample_label.setWordWrap(True)
        self.sample_label.setStyleSheet(_LOADED)
        self.unload_button = QPushButton("Unload to the safe position")
        self.unload_button.setToolTip("retract the plate / lift the arm to the rig's safe "
                                      "position, read back")
        sample.addWidget(self.sample_label, 1)
        sample.addWidget(self.unload_button)
        layout.addLayout(sample)
        self.safety = Safety()
        self.note = ""
        self._unloading = False
        self._desk: RigDesk | None = None
        self._say: Callable[[str], object] = lambda _text: None
        self.ack_button.clicked.connect(self.acknowledge)
        self.unload_button.clicked.connect(self.unload)
        self.show_safety(self.safety)

    @property
    def state(self) -> str:
        """``off`` / ``silent`` / ``armed`` / ``tripped``."""
        return self.safety.state

    def text(self) -> str:
        """What the banner says (the interlock line)."""
        return self.label.text()

    # ---- wiring -------------------------------------------------------------------------
    def bind(self, desk: RigDesk, say: Callable[[str], object]) -> None:
        """Render ``desk``'s safety state; ``say`` logs."""
        self._desk, self._say = desk, say
        desk.safety_changed.connect(self.show_safety)
        desk.alarm_changed.connect(self._on_alarm)
        desk.unloaded.connect(self._on_unloaded)
        self.show_safety(desk.safety())

    def _on_alarm(self, message: str) -> None:
        self.note = ""  # a new trip, or re-armed: an earlier refusal no longer applies
        self.show_safety(self.safety)

    # ---- actions ------------------------------------------------------------------------
    def acknowledge(self) -> None:
        """Re-arm if a fresh reading is within the limits; otherwise say why not."""
        if self._desk is None:
            return
        why = self._desk.acknowledge()
        if why:
            self.note = f"cannot re-arm yet: {why}"
            self._say(f"acknowledge refused: {why}")
        else:
            self._say("interlock trip acknowledged: interlocks armed")
        self.show_safety(self._desk.safety())

    def unload(self) -> None:
        if self._desk is not None and self._desk.unload():
            self.note, self._unloading = "", True
            self.unload_button.setEnabled(False)
            self._say("unloading the sample to the rig's safe position")
            self.show_safety(self.safety)

    def _on_unloaded(self, safe: SafeState) -> None:
        self._say(f"unload: {safe.line()}")
        self._unloading = False
        self.unload_button.setEnabled(True)
        self.show_safety(self.safety)

    # ---- drawing ------------------------------------------------------------------------
    def show_safety(self, safety: Safety) -> None:
        self.safety = safety
        fresh, stale = safety.live(LIVE)
        now = f" — now: {fresh}" if fresh else ""
        last = f" — last read: {stale}" if stale else ""
        note = f" ({self.note})" if self.note else ""
        pending = f" {safety.pending}." if safety.pending else ""
        state = safety.state
        self.ack_button.setVisible(bool(safety.alarm) and state != "off")
        if state == "off":
            self.label.setStyleSheet(_OFF)
            self.label.setText(f"Interlocks NOT MONITORING: {safety.why_off}. "
                               f"Limits: {safety.limits}{pending}")
        elif state == "silent":
            self.label.setStyleSheet(_SILENT)
            tripped = f" TRIPPED, not acknowledged: {safety.alarm}." if safety.alarm else ""
            stop = f" Last stop: {safety.safe_line}." if safety.safe_line else ""
            self.label.setText(f"NOT MONITORING: {safety.why_not_monitoring()}. Nothing is "
                               f"checked until it answers.{tripped}{stop}{pending}{last}{note}")
        elif state == "tripped":
            self.label.setStyleSheet(_TRIPPED)
            stop = safety.safe_line or "the stop is not read back yet"
            self.label.setText(f"TRIPPED: {safety.alarm}{now}{last}. {stop}. Moves toward the "
                               f"sample are refused until acknowledged.{pending}{note}")
        else:
            self.label.setStyleSheet(_OK)
            what = "every sample of the run" if safety.running else "every manual motion"
            limits = safety.limits
            if safety.overlap_armed is False:
                limits = re.sub(r"overlap ≤ ([^,]+)", r"overlap ≤ \1 NOT ARMED (first touch "
                                "unknown: run a contact search)", limits)
            self.label.setText(f"Interlocks armed ({what} is checked): {limits}{now}{last}"
                               f"{pending}")
        show = bool(safety.loaded) and not safety.running and state != "off"
        self.sample_label.setVisible(show)
        self.unload_button.setVisible(show)
        if show:
            self.sample_label.setText(f"Sample loaded ({safety.loaded}): unloading…"
                                      if self._unloading else
                                      f"Sample loaded: {safety.loaded}")
