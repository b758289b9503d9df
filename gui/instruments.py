"""Instruments panel: each instrument of the rig with its identity, connection state,
simulated or hardware, connect/disconnect, and its live readings."""

from __future__ import annotations

import html
from collections.abc import Mapping

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from gelrig.gui.fmt import quantity
from gelrig.gui.safety import GREY, NAMES, Safety, ago
from gelrig.protocols.rig import Rig
from gelrig.protocols.rigfile import RigSpec

#: instrument -> (reading key, label, SI unit) shown live.
READOUTS: dict[str, tuple[tuple[str, str, str], ...]] = {
    "stage": (("position_m", "position", "m"), ("moving", "motion", ""), ("homed", "homed", "")),
    "force": (("force_N", "force", "N"),),
    "rheometer": (("gap_m", "gap", "m"), ("angle_rad", "angle", "rad"),
                  ("theta_m", "arc travel theta", "m"), ("torque_Nm", "torque", "N*m"),
                  ("normal_force_N", "normal force", "N"), ("moving", "motion", ""),
                  ("gap_referenced", "gap referenced", "")),
}


def _identity_lines(identity: object) -> list[tuple[str, str]]:
    if isinstance(identity, Mapping):
        out = []
        for key, value in identity.items():
            if isinstance(value, Mapping):
                out.extend(_identity_lines(value))
            else:
                out.append((str(key), str(value)))
        return out
    return [("identity", str(identity))]


class InstrumentsPanel(QGroupBox):
    """Identity and live readings of every instrument; connect and disconnect the rig."""

    connect_clicked = Signal()
    disconnect_clicked = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Instruments", parent)
        layout = QVBoxLayout(self)
        self.rig_label = QLabel("no rig file")
        self.rig_label.setWordWrap(True)
        self.state_label = QLabel("disconnected")
        self.connect_button = QPushButton("Connect")
        self.disconnect_button = QPushButton("Disconnect")
        self.connect_button.setToolTip("open the rig file's instruments")
        self.disconnect_button.setToolTip("stop every axis and release the instruments")
        self.connect_button.clicked.connect(self.connect_clicked)
        self.disconnect_button.clicked.connect(self.disconnect_clicked)
        row = QHBoxLayout()
        row.addWidget(self.state_label, 1)
        row.addWidget(self.connect_button)
        row.addWidget(self.disconnect_button)
        layout.addWidget(self.rig_label)
        layout.addLayout(row)
        self.body = QVBoxLayout()
        layout.addLayout(self.body)
        self.values: dict[str, QLabel] = {}
        self.links: dict[str, QLabel] = {}  # instrument name (KDC101...) -> its link state
        self.set_connected(False)

    def set_spec(self, spec: RigSpec) -> None:
        mode = "simulated" if spec.simulated else "hardware"
        self.rig_label.setText(f"<b>{html.escape(spec.name)}</b><br>{html.escape(spec.source)}"
                               f"<br>{spec.kind} rig, {mode}")

    def set_state(self, text: str) -> None:
        self.state_label.setText(text)

    def set_connected(self, connected: bool, busy: bool = False) -> None:
        self.connect_button.setEnabled(not connected and not busy)
        self.disconnect_button.setEnabled(connected and not busy)

    def set_rig(self, rig: Rig | None) -> None:
        """One box per instrument: transport, identity, live readings."""
        while self.body.count():
            item = self.body.takeAt(0)
            widget = item.widget() if item is not None else None
            if widget is not None:
                widget.deleteLater()
        self.values.clear()
        self.links.clear()
        if rig is None:
            return
        mode = "simulated" if rig.simulated else "hardware"
        for name, identity in rig.identities.items():
            box = QGroupBox(f"{name} ({mode})")
            form = QFormLayout(box)
            for key, value in _identity_lines(identity):
                form.addRow(f"{key}:", QLabel(value))
            link = QLabel("answering")
            link.setObjectName(f"link_{name}")
            link.setToolTip("whether the instrument answers the readout (heartbeat)")
            form.addRow("<b>link</b>:", link)
            self.links[NAMES.get(name, name)] = link
            for key, label, _unit in READOUTS.get(name, ()):
                value_label = QLabel("-")
                value_label.setObjectName(f"reading_{key}")
                form.addRow(f"<b>{label}</b>:", value_label)
                self.values[key] = value_label
            self.body.addWidget(box)

    def show_safety(self, safety: Safety) -> None:
        """Each instrument's link (answering, or silent for how long and why) and its values:
        fresh as they are, otherwise greyed with their age."""
        silent = {s.name: s for s in safety.silent}
        for name, link in self.links.items():
            quiet = silent.get(name)
            link.setText(quiet.text().replace(f"{name} silent", "NOT ANSWERING") if quiet
                         else "answering")
            link.setStyleSheet("color:#b00020; font-weight:bold;" if quiet else "")
        units = {key: unit for rows in READOUTS.values() for key, _l, unit in rows}
        for key, label in self.values.items():
            if key not in safety.values:
                label.setText("-")
                continue
            value = safety.values[key]
            if key == "moving":
                text = "moving" if value else "at rest"
            elif key in ("homed", "gap_referenced"):
                text = "yes" if value else "no"
            else:
                text = quantity(value, units[key])
            fresh = safety.fresh(key)
            label.setText(text if fresh else f"{text} (last read {ago(safety.ages[key])})")
            label.setStyleSheet("" if fresh else GREY)
