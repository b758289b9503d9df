"""The strip above everything else: the interlock banner, the live values that matter while
moving (stage position and force; gap, torque, normal force), Open report and STOP.

It sits outside every scroll area and splitter, so STOP and the readouts stay in view at any
window size (issue 15: STOP was past the screen's edge at 2x scaling).
"""

from __future__ import annotations

from collections.abc import Mapping

from PySide6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QSizePolicy, QWidget

from gui.fmt import quantity

#: The values shown in the strip, in order: key, label, SI unit.
LIVE: tuple[tuple[str, str, str], ...] = (
    ("position_m", "position", "m"), ("force_N", "force", "N"), ("gap_m", "gap", "m"),
    ("theta_m", "theta", "m"), ("torque_Nm", "torque", "N*m"),
    ("normal_force_N", "normal force", "N"))
_STOP_STYLE = ("QPushButton { background:#c62828; color:white; font-weight:bold; "
               "padding:6px 18px; border-radius:4px; }")


def _shown(value: float, unit: str) -> str:
    """Lengths in mm always (as the stage and the protocol files give them), else with a
    prefix."""
    if unit == "m":
        return f"{value * 1e3:.4g} mm"
    return quantity(value, unit)


def live_text(values: Mapping[str, float]) -> str:
    """'position 6.2 mm   force 4.1 mN' from whichever live values there are."""
    return "   ".join(f"{label} {_shown(values[key], unit)}" for key, label, unit in LIVE
                       if key in values)


class Header(QWidget):
    """Banner | live values | Open report | STOP, in one row."""

    def __init__(self, banner: QWidget, parent: QWidget | None = None):
        super().__init__(parent)
        row = QHBoxLayout(self)
        row.setContentsMargins(4, 2, 4, 2)
        banner.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        row.addWidget(banner, 1)
        self.readout = QLabel("")
        self.readout.setObjectName("liveReadout")
        self.readout.setToolTip("live values (idle readouts, or the run's newest samples)")
        row.addWidget(self.readout)
        self.report_button = QPushButton("Open report")
        self.report_button.setToolTip("the last run's analysis report (HTML) in the browser")
        self.report_button.setVisible(False)
        row.addWidget(self.report_button)
        self.stop_button = QPushButton("STOP")
        self.stop_button.setObjectName("stopButton")
        self.stop_button.setStyleSheet(_STOP_STYLE)
        self.stop_button.setToolTip("stop all motion now (aborts a run) — Esc")
        row.addWidget(self.stop_button)

    def show_live(self, values: Mapping[str, float]) -> None:
        self.readout.setText(live_text(values))
