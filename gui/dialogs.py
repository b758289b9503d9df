"""Dialogs that never block STOP (issue 25): every question, message and file chooser is a
non-modal window, answered through a callback, so the main window's STOP button and Escape
keep working while one is open. Escape stops motion from any window of the application
(:class:`EscapeStops`), a dialog included.
"""

from __future__ import annotations

import inspect
import time
import weakref
from collections.abc import Callable, Sequence

from PySide6.QtCore import QEvent, QObject, QRect, Qt
from PySide6.QtGui import QKeyEvent
from PySide6.QtWidgets import QApplication, QFileDialog, QMessageBox, QWidget

#: One choice of a question: (key handed to the callback, button text, role).
Choice = tuple[str, str, QMessageBox.ButtonRole]

YES_NO: tuple[Choice, ...] = (("yes", "Yes", QMessageBox.ButtonRole.YesRole),
                              ("no", "No", QMessageBox.ButtonRole.NoRole))


def _non_modal(box: QWidget) -> None:
    box.setWindowModality(Qt.WindowModality.NonModal)
    box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    if isinstance(box, QMessageBox):
        _fit_text(box)
    box.show()
    fit_screen(box)
    box.raise_()


def _available(widget: QWidget) -> QRect:
    screen = widget.screen() or QApplication.primaryScreen()
    return screen.availableGeometry()


def _fit_text(box: QMessageBox) -> None:
    """A message too tall for the screen (a message box has a fixed size, as tall as its
    text) keeps its first paragraph in view and the whole text in its details, which
    scroll."""
    box.ensurePolished()
    room = _available(box).height() * 0.8
    if box.sizeHint().height() <= room:
        return
    text = box.text()
    head = text.split("\n\n", 1)[0]
    if len(head) > 300:
        head = head[:300].rsplit(" ", 1)[0] + " …"
    box.setText(f"{head}\n\n(the whole message: Show Details)")
    box.setDetailedText(text)


def fit_screen(window: QWidget) -> None:
    """Keep a shown top-level window within its screen's available area (1280x720, 2x
    scaling): no larger than the screen (where its minimum allows) and moved inside."""
    area = _available(window)
    frame = window.frameGeometry()
    border_w, border_h = frame.width() - window.width(), frame.height() - window.height()
    width = min(window.width(), max(area.width() - border_w, window.minimumWidth()))
    height = min(window.height(), max(area.height() - border_h, window.minimumHeight()))
    if (width, height) != (window.width(), window.height()):
        window.resize(width, height)
    frame = window.frameGeometry()
    x = max(area.left(), min(frame.left(), area.right() + 1 - frame.width()))
    y = max(area.top(), min(frame.top(), area.bottom() + 1 - frame.height()))
    if (x, y) != (frame.left(), frame.top()):
        window.move(x, y)


def ask(parent: QWidget, title: str, text: str, on_answer: Callable[[str], object],
        choices: Sequence[Choice] = YES_NO, default: str = "no") -> QMessageBox:
    """A non-modal question; ``on_answer(key)`` once a choice is clicked (closing the box or
    Escape answers ``default``'s escape: nothing, the callback is not called)."""
    box = QMessageBox(QMessageBox.Icon.Question, title, text, QMessageBox.StandardButton.NoButton,
                      parent)
    box.setObjectName("question")
    keys = {}
    for key, label, role in choices:
        button = box.addButton(label, role)
        button.setToolTip(label)
        keys[button] = key
        if key == default:
            box.setDefaultButton(button)

    def clicked(button: object) -> None:
        key = keys.get(button)  # type: ignore[call-overload]
        if key is not None:
            on_answer(key)

    box.buttonClicked.connect(clicked)
    _non_modal(box)
    return box


def inform(parent: QWidget, title: str, text: str,
           icon: QMessageBox.Icon = QMessageBox.Icon.Critical) -> QMessageBox:
    """A non-modal message with OK."""
    box = QMessageBox(icon, title, text, QMessageBox.StandardButton.Ok, parent)
    box.setObjectName("faultMessage")
    _non_modal(box)
    return box


def choose(parent: QWidget, title: str, start: str, on_path: Callable[[str], object],
           filters: str = "", folder: bool = False, save: bool = False) -> QFileDialog:
    """A non-modal file (or folder) chooser; ``on_path(path)`` once one is chosen."""
    dialog = QFileDialog(parent, title, start, filters)
    dialog.setObjectName("fileChooser")
    dialog.setOption(QFileDialog.Option.DontUseNativeDialog)  # a native one may be modal
    if folder:
        dialog.setFileMode(QFileDialog.FileMode.Directory)
        dialog.setOption(QFileDialog.Option.ShowDirsOnly)
    elif save:
        dialog.setAcceptMode(QFileDialog.AcceptMode.AcceptSave)
    else:
        dialog.setFileMode(QFileDialog.FileMode.ExistingFile)

    def chosen() -> None:
        files = dialog.selectedFiles()
        if files:
            on_path(files[0])

    dialog.accepted.connect(chosen)
    _non_modal(dialog)
    return dialog


#: Key presses closer than this (s) are one press seen on its way through the widgets.
_SAME_PRESS = 0.1


class EscapeStops(QObject):
    """Application-wide: Escape in any window (a dialog included) calls ``stop``; the key
    goes on to the window too (a dialog still closes)."""

    def __init__(self, stop: Callable[[], object], parent: QObject | None = None):
        super().__init__(parent)
        # weakly: a Qt object holding its window's method makes a cycle that the garbage
        # collector cannot take apart safely (PySide6: a crash when the window is collected)
        self._stop = weakref.WeakMethod(stop) if inspect.ismethod(stop) else lambda: stop
        self._last = -1.0

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 (Qt override)
        if (event.type() == QEvent.Type.KeyPress and isinstance(event, QKeyEvent)
                and event.key() == Qt.Key.Key_Escape and not event.isAutoRepeat()):
            now = time.monotonic()
            stop = self._stop()
            if now - self._last > _SAME_PRESS and stop is not None:
                self._last = now
                stop()
        return False

    def install(self) -> None:
        app = QApplication.instance()
        if app is not None:
            app.installEventFilter(self)

    def remove(self) -> None:
        app = QApplication.instance()
        if app is not None:
            app.removeEventFilter(self)
