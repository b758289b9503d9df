"""The strip above everything else: the interlock banner, the live values that matter while
moving (stage position and force; gap, torque, normal force), Open report and STOP.

It sits outside every scroll area and splitter, so STOP and the readouts stay in view at any
window size (issue 15: STOP was past the screen's edge at 2x scaling).
"""

from __future__ import annotations

from collections.abc import Mapping

from PySide6.QtCore import Qt
from PySide6.QtGui import QResizeEvent
from PySide6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QSizePolicy, QWidget

from gelrig.gui.fmt import quantity
from gelrig.gui.safety import GREY, Safety

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

        self.stale = QLabel("")
        self.stale.setObjectName("staleReadout")
        self.stale.setStyleSheet(GREY)
        self.stale.setToolTip("values of an instrument that stopped answering, with their age")
        row.insertWidget(2, self.stale)

    def show_live(self, values: Mapping[str, float]) -> None:
        self.readout.setText(live_text(values))

    def show_safety(self, safety: Safety) -> None:
        """Fresh values as they are; an instrument's values that are not fresh greyed, with
        their age; nothing without a rig."""
        if not safety.connected:
            self.readout.setText("")
            self.stale.setText("")
            return
        fresh, stale = safety.live(LIVE)
        self.readout.setText(fresh.replace(", ", "   "))
        self.stale.setText(stale.replace(", ", "   "))


class StatusLine(QLabel):
    """A one-line status that never widens its window: shown elided ("…") at the width it
    is given, the whole line in ``full`` and in its tooltip. Its size never depends on its
    text, so setting the text on a resize cannot feed back into the layout."""

    def __init__(self, tip: str, parent: QWidget | None = None):
        super().__init__("", parent)
        self.full, self.tip = "", tip
        self.setMinimumWidth(0)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setToolTip(tip)

    def set_line(self, line: str) -> None:
        self.full = line
        self.setToolTip(f"{line}\n({self.tip})" if line else self.tip)
        self._elide()

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        self._elide()

    def _elide(self) -> None:
        shown = self.fontMetrics().elidedText(self.full, Qt.TextElideMode.ElideRight,
                                              max(self.width(), 1))
        if shown != self.text():
            self.setText(shown)
