"""Manual control: stage home / jog / move to, load-cell tare (compression); rheometer gap,
rotation at a speed, hold (shear). Disabled while a protocol runs; the window's Stop button
(always enabled) stops everything.

Each button emits a command: a label and either a function of the rig or a
:class:`~gelrig.protocols.manual_motion.Motion`, which the session runs on the rig thread under the
interlocks (ADR 0170). Entries are in lab units (mm, mm/s, s) and converted to SI here. A
stage move before homing asks to home first.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QGridLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from gelrig.gui import dialogs
from gelrig.protocols.manual_motion import APPROACH_SPEED, Motion, approach_speed
from gelrig.protocols.rig import CompressionRig, Rig, ShearRig

Command = Callable[[Rig], object] | Motion


def _spin(value: float, lo: float, hi: float, unit: str, decimals: int = 3,
          step: float = 0.1, what: str = "") -> QDoubleSpinBox:
    """A value field in ``unit`` with its allowed range, both said in its tooltip."""
    box = QDoubleSpinBox()
    box.setToolTip(f"{what}\nin {unit}, allowed {lo:g} to {hi:g} {unit}".lstrip())
    box.setRange(lo, hi)
    box.setDecimals(decimals)
    box.setSingleStep(step)
    box.setValue(value)
    box.setSuffix(f" {unit}")
    return box


def _home_motion() -> Motion:
    """Homing moves the plate away from the sphere (to position 0): it unloads."""
    return Motion(lambda rig: _compression(rig).home(), lambda rig: False)


def _compression(rig: Rig) -> CompressionRig:
    if not isinstance(rig, CompressionRig):
        raise TypeError("not a compression rig")
    return rig


def _shear(rig: Rig) -> ShearRig:
    if not isinstance(rig, ShearRig):
        raise TypeError("not a shear rig")
    return rig


#: Each manual button's tooltip: what it does and how it is watched.
TIPS: dict[str, str] = {
    "home": "home the stage: the plate goes back to position 0, away from the sphere (Ctrl+H)",
    "jog_minus": "move the plate the jog step away from the sphere, at the speed above",
    "jog_plus": "move the plate the jog step toward the sphere, under the interlocks (before "
                "a contact search: asks, and at most 0.3 mm/s)",
    "move_to": "move the plate to the position, under the interlocks (toward the sphere "
               "before a contact search: asks, and at most 0.3 mm/s)",
    "tare": "zero the load cell on the mean force over the time given (unload it first)",
    "zero_gap": "reference the rheometer's gap (needed before any gap move)",
    "set_gap": "move the lift to the gap, under the interlocks",
    "rotate": "turn the arm at the speed until stopped, under the interlocks",
    "hold": "hold the arm where it is",
}


class ManualPanel(QGroupBox):
    """Buttons and entries for the instruments of one rig kind."""

    command = Signal(str, object)  # what, Command

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Manual control", parent)
        self.layout_ = QVBoxLayout(self)
        self.body: QWidget | None = None
        self.buttons: dict[str, QPushButton] = {}
        self.entries: dict[str, QDoubleSpinBox] = {}
        self.kind: str | None = None
        #: from the readouts: whether the stage is homed (None: not known yet)
        self.homed: bool | None = None
        #: the plate's position from the readouts (m; None: not known yet)
        self.position: float | None = None
        #: whether first touch is known (set by the window: the rig tells)
        self.first_touch_known: Callable[[], bool] | None = None

    def show_readings(self, values: Mapping[str, float]) -> None:
        """Follow the readouts (whether the stage is homed)."""
        if "homed" in values:
            self.homed = bool(values["homed"])
        if "position_m" in values:
            self.position = values["position_m"]

    def home_first(self) -> bool:
        """Before a stage move: True to go on. Not homed: ask to home first (a dialog)."""
        if self.kind != "compression" or self.homed is not False:
            return True
        dialogs.ask(self, "Home the stage first",
                    "The stage is not homed, so its positions mean nothing yet and a move "
                    "could press into the sample.\n\nHome it now? (Move again once it is "
                    "homed.)", lambda key: self.command.emit("stage home", _home_motion())
                    if key == "yes" else None, default="yes")
        return False

    def _confirm_approach(self, what: str, confirmed: Callable[[], Command]) -> None:
        """A move toward the sample before a contact search: ask (non-modal) first."""
        dialogs.ask(self, "First touch is not known",
                    "No contact search has found first touch yet, so the overlap limit is not "
                    f"armed and this move may press into the sample.\n\nMove at most "
                    f"{APPROACH_SPEED * 1e3:g} mm/s toward the sample, with only the force "
                    "limit armed?",
                    lambda key: self.command.emit(what, confirmed()) if key == "yes" else None)

    def set_kind(self, kind: str | None) -> None:
        if kind == self.kind:
            return
        self.kind, self.homed = kind, None
        if self.body is not None:
            self.body.deleteLater()
        self.buttons.clear()
        self.entries.clear()
        self.body = QWidget()
        self.layout_.addWidget(self.body)
        if kind == "compression":
            self._build_compression(self.body)
        elif kind == "shear":
            self._build_shear(self.body)
        else:
            QVBoxLayout(self.body).addWidget(QLabel("connect a rig"))

    def _button(self, key: str, text: str, what: str, make: Callable[[], Command],
                needs_home: bool = False, toward: Callable[[], bool] | None = None,
                confirmed: Callable[[], Command] | None = None) -> QPushButton:
        button = QPushButton(text)
        button.setToolTip(TIPS.get(key, what))

        def clicked() -> None:
            if needs_home and not self.home_first():
                return
            if toward is not None and confirmed is not None and toward() \
                    and self.first_touch_known is not None and not self.first_touch_known():
                self._confirm_approach(what, confirmed)
                return
            self.command.emit(what, make())

        button.clicked.connect(clicked)
        self.buttons[key] = button
        return button

    def _build_compression(self, body: QWidget) -> None:
        grid = QGridLayout(body)
        e = self.entries
        e["speed"] = _spin(0.5, 0.001, 2.3, "mm/s", what="the plate's speed for Jog and "
                           "Move (0.3 mm/s at most toward the sample before a contact search)")
        e["step"] = _spin(0.1, 0.001, 5.0, "mm", step=0.05, what="how far one Jog moves")
        e["target"] = _spin(0.0, 0.0, 25.0, "mm", decimals=4, what="the plate position Move "
                            "goes to (0: home, away from the sphere)")
        e["tare"] = _spin(1.0, 0.01, 60.0, "s", decimals=2, what="the tare is the mean force "
                          "over this time; unload the cell first")
        e["tare"].setPrefix("average over ")  # what the seconds are for

        def move(relative: float | None, confirmed: bool = False) -> Command:
            speed = e["speed"].value() * 1e-3
            target = None if relative is not None else e["target"].value() * 1e-3

            def start(rig: Rig) -> None:
                plate = _compression(rig)  # refused, or slowed, before a contact search
                plate.move_plate(approach_speed(plate, speed, target, relative, confirmed),
                                 target, relative)

            return Motion(start, lambda rig: _compression(rig).toward(target, relative))

        grid.addWidget(QLabel("<b>Stage</b>"), 0, 0)
        grid.addWidget(self._button("home", "Home", "stage home", _home_motion), 0, 1)
        grid.addWidget(QLabel("speed"), 1, 0)
        grid.addWidget(e["speed"], 1, 1, 1, 2)
        grid.addWidget(QLabel("jog step"), 2, 0)
        grid.addWidget(e["step"], 2, 1, 1, 2)
        def toward_target() -> bool:
            return self.position is None or e["target"].value() * 1e-3 > self.position

        grid.addWidget(self._button("jog_minus", "Jog − (away)", "stage jog −",
                                    lambda: move(-e["step"].value() * 1e-3), True), 3, 1)
        grid.addWidget(self._button("jog_plus", "Jog + (toward sphere)", "stage jog +",
                                    lambda: move(e["step"].value() * 1e-3), True,
                                    toward=lambda: True,
                                    confirmed=lambda: move(e["step"].value() * 1e-3, True)),
                       3, 2)
        grid.addWidget(QLabel("move to"), 4, 0)
        grid.addWidget(e["target"], 4, 1)
        grid.addWidget(self._button("move_to", "Move", "stage move to", lambda: move(None),
                                    True, toward=toward_target,
                                    confirmed=lambda: move(None, True)), 4, 2)
        grid.addWidget(QLabel("<b>Load cell</b>"), 5, 0)
        grid.addWidget(e["tare"], 5, 1)

        def tare() -> Command:
            duration = e["tare"].value()
            return lambda rig: _compression(rig).tare(duration)

        grid.addWidget(self._button("tare", "Tare", "load-cell tare", tare), 5, 2)
        grid.setRowStretch(6, 1)  # rows keep their height; the space left goes below them

    def _build_shear(self, body: QWidget) -> None:
        grid = QGridLayout(body)
        e = self.entries
        e["gap"] = _spin(8.0, 0.0, 50.0, "mm", decimals=3, what="the gap Set gap goes to")
        e["speed"] = _spin(0.5, -5.0, 5.0, "mm/s", decimals=4, step=0.05,
                           what="linear speed at the arm for Rotate (+ clockwise); "
                           "rpm = v / (2 pi L) * 60")

        def set_gap() -> Command:
            gap = e["gap"].value() * 1e-3
            return Motion(lambda rig: _shear(rig).set_gap(gap),
                          lambda rig: gap < _shear(rig).rheometer.gap())

        def rotate() -> Command:
            speed = e["speed"].value() * 1e-3
            return Motion(lambda rig: _shear(rig).rotate(speed), ends=False)

        grid.addWidget(QLabel("<b>Rheometer</b>"), 0, 0)
        grid.addWidget(self._button("zero_gap", "Reference gap", "rheometer gap reference",
                                    lambda: lambda rig: _shear(rig).zero_gap()), 0, 1)
        grid.addWidget(QLabel("gap"), 1, 0)
        grid.addWidget(e["gap"], 1, 1)
        grid.addWidget(self._button("set_gap", "Set gap", "rheometer gap", set_gap), 1, 2)
        grid.addWidget(QLabel("speed at the arm (+ clockwise)"), 2, 0)
        grid.addWidget(e["speed"], 2, 1)
        grid.addWidget(self._button("rotate", "Rotate", "rheometer rotate", rotate), 2, 2)
        grid.addWidget(self._button("hold", "Hold position", "rheometer hold",
                                    lambda: lambda rig: _shear(rig).hold()), 3, 1)
        grid.setRowStretch(4, 1)

    def set_enabled(self, enabled: bool) -> None:
        """Manual commands only while connected and no protocol runs."""
        for widget in (*self.buttons.values(), *self.entries.values()):
            widget.setEnabled(enabled)
