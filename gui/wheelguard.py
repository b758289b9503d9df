"""Value fields change only when focused: the mouse wheel over an unfocused spin box or combo
box scrolls the panel around it, never the value (issue 15: scrolling over manual control
changed jog step, speed and move-to without a click).

One event filter on the application covers every such field, present and future (the manual
panel rebuilds its fields when the rig kind changes): each gets the strong focus policy (a
click or Tab focuses it, the wheel does not) and its wheel events are ignored unless it has
focus, so they propagate to the enclosing scroll area.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtWidgets import QAbstractSpinBox, QApplication, QComboBox, QWidget

_FIELDS = (QAbstractSpinBox, QComboBox)


class WheelGuard(QObject):
    """Application event filter: no wheel changes to an unfocused value field."""

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:  # noqa: N802 (Qt override)
        kind = event.type()
        if kind == QEvent.Type.Wheel and isinstance(obj, _FIELDS) and not obj.hasFocus():
            parent = obj.parentWidget()  # the panel (and the scroll area around it) scrolls
            if parent is not None:
                QApplication.sendEvent(parent, event)
            return True
        elif kind == QEvent.Type.Polish and isinstance(obj, _FIELDS):
            guard(obj)
        return False


def guard(widget: QWidget) -> None:
    """Focus by click or Tab only (not by the wheel)."""
    widget.setFocusPolicy(Qt.FocusPolicy.StrongFocus)


_installed: WheelGuard | None = None


def install(app: QApplication) -> WheelGuard:
    """Install the guard on ``app`` once (idempotent); returns it."""
    global _installed
    if _installed is None:
        _installed = WheelGuard(app)
        app.installEventFilter(_installed)
    return _installed
