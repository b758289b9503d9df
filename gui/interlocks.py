"""The interlock banner: always visible and always true. Grey "not monitoring" while no rig
answers; green "armed" with the live values while connected (every manual motion and every
run is checked sample by sample); red "tripped" with the live value after a trip or fault,
and an Acknowledge that re-arms once the condition has cleared. Below it, whether the sample
is loaded, with an Unload that puts it in the rig's safe position."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from PySide6.QtWidgets import QFrame, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from gui.fmt import quantity
from gui.rigsession import RigSession
from protocols.rig import CompressionLimits, ShearLimits
from protocols.safestop import SafeState

_OK = "background:#d8f5d0; color:#14521a; padding:6px; border-radius:4px;"
_OFF = "background:#e0e0e0; color:#333333; padding:6px; border-radius:4px;"
_TRIPPED = "background:#c62828; color:white; font-weight:bold; padding:6px; border-radius:4px;"
_LOADED = "background:#fff3c4; color:#5d4200; padding:4px; border-radius:4px;"

#: live value key -> (what, SI unit), in the order shown
LIVE = (("force_N", "force", "N"), ("torque_Nm", "torque", "N*m"),
        ("normal_force_N", "normal force", "N"))


def limits_text(limits: CompressionLimits | ShearLimits | None) -> str:
    if limits is None:
        return "no rig"
    return ", ".join(f"{what} ≤ {quantity(value, unit)}" for what, value, unit in limits.guards())


class InterlockBanner(QFrame):
    """Interlock state: ``off`` (not monitoring), ``armed`` or ``tripped``; and the sample."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        row = QHBoxLayout()
        self.label = QLabel()
        self.label.setWordWrap(True)
        # two lines always fit (the splitter may not squeeze the state out of sight)
        self.label.setMinimumHeight(2 * self.label.fontMetrics().lineSpacing() + 14)
        self.ack_button = QPushButton("Acknowledge")
        self.ack_button.setToolTip("re-arm the interlocks (once the condition has cleared)")
        row.addWidget(self.label, 1)
        row.addWidget(self.ack_button)
        layout.addLayout(row)
        sample = QHBoxLayout()
        self.sample_label = QLabel()
        self.sample_label.setWordWrap(True)
        self.sample_label.setStyleSheet(_LOADED)
        self.unload_button = QPushButton("Unload to the safe position")
        sample.addWidget(self.sample_label, 1)
        sample.addWidget(self.unload_button)
        layout.addLayout(sample)
        self.state = "off"
        self.why_off = "no rig connected"
        self.message = ""
        self.note = ""
        self.running = False
        self.loaded = ""
        self._limits = "no rig"
        self._live = ""
        self._session: RigSession | None = None
        self._say: Callable[[str], object] = lambda _text: None
        self.ack_button.clicked.connect(self.acknowledge)
        self.unload_button.clicked.connect(self.unload)
        self._render()

    def text(self) -> str:
        """What the banner says (the interlock line)."""
        return self.label.text()

    # ---- wiring -------------------------------------------------------------------------
    def bind(self, session: RigSession, say: Callable[[str], object]) -> None:
        """Follow ``session`` (connection, readouts, alarm, sample, runs); ``say`` logs."""
        self._session, self._say = session, say
        session.connected.connect(lambda rig: self.monitoring(rig.limits))
        session.disconnected.connect(lambda: self.not_monitoring("disconnected"))
        session.connect_failed.connect(lambda _m: self.not_monitoring("the rig did not connect"))
        session.readings.connect(self.live)
        session.alarm_changed.connect(self._on_alarm)
        session.load_changed.connect(self.set_loaded)
        session.unloaded.connect(self._on_unloaded)
        session.run_started.connect(lambda _path: self._set_running(True))
        session.run_finished.connect(lambda _state, _reason: self._set_running(False))

    # ---- state --------------------------------------------------------------------------
    def set_limits(self, limits: CompressionLimits | ShearLimits | None) -> None:
        self._limits = limits_text(limits)
        self._render()

    def monitoring(self, limits: CompressionLimits | ShearLimits | None = None) -> None:
        """A rig answers: the interlocks are armed (unless a trip is unacknowledged)."""
        if limits is not None:
            self._limits = limits_text(limits)
        if self.state == "off":
            self.state = "armed"
        self._render()

    def not_monitoring(self, why: str) -> None:
        """No rig answers: nothing is checked, no live value is shown."""
        self.state, self.why_off, self.message, self.note = "off", why, "", ""
        self._live, self.loaded = "", ""
        self._render()

    def trip(self, message: str) -> None:
        self.state, self.message, self.note = "tripped", message, ""
        self._render()

    def armed(self) -> None:
        """The interlocks are armed again (a trip was acknowledged)."""
        self.state, self.message, self.note = "armed", "", ""
        self._render()

    def _on_alarm(self, message: str) -> None:
        if message:
            self.trip(message)
        elif self.state == "tripped":
            self.armed()

    def _set_running(self, running: bool) -> None:
        self.running = running
        if running:
            self.loaded = ""
        self._render()

    def set_loaded(self, why: str) -> None:
        self.loaded = why
        self._render()

    def live(self, values: Mapping[str, float]) -> None:
        if self.state == "off":
            return
        live = ", ".join(f"{what} {quantity(values[key], unit)}" for key, what, unit in LIVE
                         if key in values)
        if live and live != self._live:
            self._live = live
            self._render()

    # ---- actions ------------------------------------------------------------------------
    def acknowledge(self) -> None:
        """Re-arm if the condition has cleared; otherwise say why not."""
        if self._session is None:
            self.armed()
            return
        why = self._session.acknowledge()
        if why:
            self.note = f"cannot re-arm yet: {why}"
            self._say(f"acknowledge refused: {why}")
        else:
            self._say("interlock trip acknowledged: interlocks armed")
        self._render()

    def unload(self) -> None:
        if self._session is not None and self._session.unload():
            self.note = ""
            self.sample_label.setText(f"Sample loaded ({self.loaded}): unloading…")
            self.unload_button.setEnabled(False)
            self._say("unloading the sample to the rig's safe position")

    def _on_unloaded(self, safe: SafeState) -> None:
        self._say(f"unload: {safe.line()}")
        self.unload_button.setEnabled(True)
        self._render()

    # ---- drawing ------------------------------------------------------------------------
    def _render(self) -> None:
        now = f" — now: {self._live}" if self._live else ""
        note = f" ({self.note})" if self.note else ""
        self.ack_button.setVisible(self.state == "tripped")
        if self.state == "tripped":
            self.label.setStyleSheet(_TRIPPED)
            self.label.setText(f"TRIPPED: {self.message}{now}. Motion was stopped; moves "
                               f"toward the sample are refused until acknowledged{note}")
        elif self.state == "off":
            self.label.setStyleSheet(_OFF)
            self.label.setText(f"Interlocks NOT MONITORING: {self.why_off}. "
                               f"Limits: {self._limits}")
        else:
            self.label.setStyleSheet(_OK)
            what = "every sample of the run" if self.running else "every manual motion"
            self.label.setText(f"Interlocks armed ({what} is checked): {self._limits}{now}")
        show = bool(self.loaded) and not self.running and self.state != "off"
        self.sample_label.setVisible(show)
        self.unload_button.setVisible(show)
        if show:
            self.sample_label.setText(f"Sample loaded: {self.loaded}")
