"""The interlock banner: always visible, green while the limits hold, red once one trips or a
fault stopped the rig, with the limits and the live value they guard."""

from __future__ import annotations

from collections.abc import Mapping

from PySide6.QtWidgets import QLabel, QWidget

from gui.fmt import quantity
from protocols.rig import CompressionLimits, ShearLimits

_OK = "background:#d8f5d0; color:#14521a; padding:6px; border-radius:4px;"
_TRIPPED = "background:#c62828; color:white; font-weight:bold; padding:6px; border-radius:4px;"


def limits_text(limits: CompressionLimits | ShearLimits | None) -> str:
    if limits is None:
        return "no rig"
    return ", ".join(f"{what} ≤ {quantity(value, unit)}" for what, value, unit in limits.guards())


class InterlockBanner(QLabel):
    """Interlock state: 'ok', 'armed' (a run is checking every sample) or 'tripped'."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.setWordWrap(True)
        self.state = "ok"
        self.message = ""
        self._limits = "no rig"
        self._live = ""
        self._render()

    def set_limits(self, limits: CompressionLimits | ShearLimits | None) -> None:
        self._limits = limits_text(limits)
        self._render()

    def armed(self) -> None:
        """A run starts: interlocks are checked on every sample; a previous trip is cleared."""
        self.state, self.message = "armed", ""
        self._render()

    def disarmed(self) -> None:
        if self.state == "armed":
            self.state = "ok"
        self._render()

    def trip(self, message: str) -> None:
        self.state, self.message = "tripped", message
        self._render()

    def live(self, values: Mapping[str, float]) -> None:
        parts = []
        if "force_N" in values:
            parts.append(f"force {quantity(values['force_N'], 'N')}")
        if "torque_Nm" in values:
            parts.append(f"torque {quantity(values['torque_Nm'], 'N*m')}")
        if "normal_force_N" in values:
            parts.append(f"normal force {quantity(values['normal_force_N'], 'N')}")
        live = ", ".join(parts)
        if live != self._live:
            self._live = live
            self._render()

    def _render(self) -> None:
        now = f" — now: {self._live}" if self._live else ""
        if self.state == "tripped":
            self.setStyleSheet(_TRIPPED)
            self.setText(f"STOPPED: {self.message}. Motion was stopped. Limits: {self._limits}")
            return
        self.setStyleSheet(_OK)
        what = "armed (checked on every sample)" if self.state == "armed" else "ok"
        self.setText(f"Interlocks {what}: {self._limits}{now}")
