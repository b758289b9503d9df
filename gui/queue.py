"""The Queue tab (issue 28, item 6): protocols queued with their parameter values, or a sweep
over one parameter, run one after another (:class:`~gelrig.gui.queue_runner.QueueRunner`).

"Add the protocol shown" queues the Protocol tab's file or script as it is saved, with its
script parameters, the Sample fields and the run record; a parameter and a list of values
make one item per value (``step[1].hold`` = ``300 s; 600 s; 1200 s``).
"""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from gelrig.gui.queue_items import STOPPED, QueueItem, split_values, sweep
from gelrig.gui.queue_runner import QueueRunner

_ERROR = "color:#c62828;"


class QueuePanel(QWidget):
    """The queue's list and its controls. ``current()`` gives the protocol shown as an item
    (or the one line why it cannot be queued); ``ask_start(then)`` asks what Run asks first
    (the sample loaded) and calls ``then``."""

    def __init__(self, runner: QueueRunner, current: Callable[[], QueueItem | str],
                 ask_start: Callable[[Callable[[], object]], object],
                 parent: QWidget | None = None):
        super().__init__(parent)
        self.runner, self.current, self.ask_start = runner, current, ask_start
        layout = QVBoxLayout(self)
        head = QLabel("Runs one after another, each rehearsed on the rig's twin first; stops "
                      "at the first run that does not complete.")
        head.setWordWrap(True)
        layout.addWidget(head)
        grid = QGridLayout()
        self.param = QLineEdit()
        self.param.setObjectName("queue_param")
        self.param.setPlaceholderText("step[1].hold, or a script's parameter")
        self.param.setToolTip("a parameter to set (a protocol file's step[i].field or "
                              "'<step name>.field'; a script's keyword); empty: as shown")
        self.values = QLineEdit()
        self.values.setObjectName("queue_values")
        self.values.setPlaceholderText("300 s; 600 s; 1200 s")
        self.values.setToolTip("its value, or several separated by ';' (or ','): a sweep, "
                               "one queued run per value")
        grid.addWidget(QLabel("parameter"), 0, 0)
        grid.addWidget(self.param, 0, 1)
        grid.addWidget(QLabel("values"), 1, 0)
        grid.addWidget(self.values, 1, 1)
        layout.addLayout(grid)
        self.add_button = QPushButton("Add the protocol shown")
        self.add_button.setToolTip("queue the Protocol tab's file or script (as saved) with "
                                   "its parameters, the Sample fields and the run record")
        self.add_button.clicked.connect(self.add_current)
        layout.addWidget(self.add_button)
        self.list = QListWidget()
        self.list.setObjectName("queue_list")
        layout.addWidget(self.list, 1)
        buttons = QHBoxLayout()
        self.start_button = QPushButton("Start queue")
        self.stop_button = QPushButton("Stop queue")
        self.stop_button.setToolTip("start no further run (the run going on goes on: Abort "
                                    "or STOP ends it)")
        self.remove_button = QPushButton("Remove")
        self.clear_button = QPushButton("Clear finished")
        self.start_button.setToolTip("run the queued items in turn, from the first waiting "
                                     "one; each is rehearsed on the rig's twin first")
        self.remove_button.setToolTip("take the selected item out of the queue")
        self.clear_button.setToolTip("drop the items that ran or where the queue stopped")
        self.start_button.clicked.connect(lambda: self.ask_start(self.runner.start))
        self.stop_button.clicked.connect(self.runner.stop)
        self.remove_button.clicked.connect(lambda: self.runner.remove(self.list.currentRow()))
        self.clear_button.clicked.connect(self.runner.clear_finished)
        for button in (self.start_button, self.stop_button, self.remove_button,
                       self.clear_button):
            buttons.addWidget(button)
        layout.addLayout(buttons)
        self.status = QLabel()
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.status)
        runner.changed.connect(self.show_items)
        self.show_items()

    def add_current(self) -> list[QueueItem]:
        """Queue the protocol shown (one item per value of the parameter, if one is given)."""
        base = self.current()
        if isinstance(base, str):
            self._say(base, error=True)
            return []
        name, values = self.param.text().strip(), split_values(self.values.text())
        if name and not values:
            self._say(f"give the values of {name} (separated by ';')", error=True)
            return []
        items = sweep(base, name, values) if name else [base]
        for item in items:  # checked now: a bad value is said here, not when its turn comes
            try:
                item.procedure()
            except Exception as exc:
                self._say(f"not queued: {exc}", error=True)
                return []
        self.runner.add(items)
        self._say(f"queued {len(items)} run(s)")
        return items

    def show_items(self) -> None:
        self.list.clear()
        for n, item in enumerate(self.runner.items, start=1):
            text = f"{n}. [{item.state}] {item.label()}"
            row = QListWidgetItem(text + (f" — {item.reason}" if item.reason else ""))
            row.setToolTip("\n".join(filter(None, [item.path, item.reason, item.run])))
            if item.state == STOPPED:
                row.setForeground(Qt.GlobalColor.darkRed)
            self.list.addItem(row)
        busy = self.runner.active
        self.start_button.setEnabled(not busy)
        self.stop_button.setEnabled(busy)
        self._say(self.runner.message, error=self.runner.message.startswith("queue stopped at"))

    def _say(self, text: str, error: bool = False) -> None:
        self.status.setText(text)
        self.status.setStyleSheet(_ERROR if error else "")
