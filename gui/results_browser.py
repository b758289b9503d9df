"""The Results tab (issue 28, item 5): the runs of the runs folder, found as ``gelrig runs``
finds them, opened in the run view or overlaid.

The list comes from the catalog (``ROOT/.gelrig-runs.sqlite``) through the same query code as
``gelrig runs`` and ``gelrig.runs`` (:func:`gelrig.catalog.find_runs`: the index brought up
to date, rebuilt when missing or damaged with one warning line, read from the folders when
locked), with the same filters: sample, operator, protocol, status (``*`` wildcards), tag,
since, until. A bad filter is its one line under the filters; the list is left as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGridLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from gelrig.catalog import find_runs
from gelrig.gui import offthread
from gelrig.gui.compare_view import CompareView, curves_of
from gelrig.instrument.core.catalog import select_entries
from gelrig.instrument.core.errors import ConfigError

#: Filters: key (a ``find_runs`` keyword), placeholder.
FILTERS = (("sample", "gel-A*"), ("operator", "ada"), ("protocol", "*hold*"),
           ("status", "completed, interrupted"), ("tag", "week48"),
           ("since", "2026-11-25 or 7d"), ("until", "2026-11-30"))
#: Columns: title, the catalog entry's key.
COLUMNS = (("run", "name"), ("started", "started"), ("sample", "sample"),
           ("operator", "operator"), ("protocol", "protocol"), ("status", "status"),
           ("tags", "tags"), ("note", "note"))
_ERROR = "color:#c62828;"


def filter_values(texts: dict[str, str]) -> dict[str, Any]:
    """The filters typed: sample, operator, protocol, status and tag take comma-separated
    values (any of them; all of the tags), since and until one time each."""
    out: dict[str, Any] = {}
    for key, text in texts.items():
        text = text.strip()
        if not text:
            continue
        if key in ("since", "until"):
            out[key] = text
        else:
            out[key] = [part.strip() for part in text.split(",") if part.strip()]
    return out


def cell_text(entry: dict[str, Any], key: str) -> str:
    value = entry.get(key)
    text = ", ".join(value) if isinstance(value, list) else str(value or "")
    if key == "status" and entry.get("status") != entry.get("recorded_status"):
        text += f" (run.json: {entry.get('recorded_status')})"  # as gelrig runs shows it
    return text


class ResultsBrowser(QWidget):
    """Filters, the runs found, Open and Compare, and the comparison below.

    ``open_run(path)`` opens a run in the run view; ``warn(line)`` is told each warning
    line of the catalog (a damaged index rebuilt, a locked one not used). The list and a
    comparison are read on threads; ``refreshing`` and ``loading`` say they are under way."""

    def __init__(self, root: Path, open_run: Callable[[Path], object],
                 warn: Callable[[str], object] | None = None, parent: QWidget | None = None):
        super().__init__(parent)
        self.root = root
        self.open_run = open_run
        self.warn = warn
        self.entries: list[dict[str, Any]] = []
        self.warnings: list[str] = []
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        grid = QGridLayout()
        grid.setHorizontalSpacing(4)
        grid.setVerticalSpacing(2)
        self.filters: dict[str, QLineEdit] = {}
        for i, (key, placeholder) in enumerate(FILTERS):
            edit = QLineEdit()
            edit.setObjectName(f"filter_{key}")
            edit.setPlaceholderText(placeholder)
            edit.setToolTip(f"only runs with this {key} (as gelrig runs --{key})")
            edit.returnPressed.connect(self.refresh)
            grid.addWidget(QLabel(key), i // 4, 2 * (i % 4))
            grid.addWidget(edit, i // 4, 2 * (i % 4) + 1)
            self.filters[key] = edit
        layout.addLayout(grid)
        buttons = QHBoxLayout()
        self.find_button = QPushButton("Find")
        self.find_button.setToolTip("list the runs of the runs folder that match the filters")
        self.open_button = QPushButton("Open")
        self.open_button.setToolTip("open the selected run in the run view")
        self.compare_button = QPushButton("Compare")
        self.compare_button.setToolTip("overlay the selected runs' curves and put their "
                                       "fitted values side by side")
        self.find_button.clicked.connect(self.refresh)
        self.open_button.clicked.connect(self.open_selected)
        self.compare_button.clicked.connect(self.compare_selected)
        for button in (self.find_button, self.open_button, self.compare_button):
            buttons.addWidget(button)
        self.status = QLabel()
        self.status.setWordWrap(True)
        buttons.addWidget(self.status, 1)
        layout.addLayout(buttons)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels([title for title, _ in COLUMNS])
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.ExtendedSelection)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.horizontalHeader().setSectionResizeMode(
            QHeaderView.ResizeMode.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(self.fontMetrics().height() + 6)
        self.table.itemSelectionChanged.connect(self._update_buttons)
        self.table.doubleClicked.connect(lambda _index: self.open_selected())
        self.compare = CompareView()
        split = QSplitter(Qt.Orientation.Vertical)
        split.addWidget(self.table)
        split.addWidget(self.compare)
        split.setStretchFactor(0, 1)
        split.setStretchFactor(1, 3)
        split.setSizes([130, 510])  # the list short, the comparison tall
        self.table.setMinimumHeight(80)
        layout.addWidget(split, 1)
        self._token = self._list_token = 0
        self.loading = False  # a comparison is being read
        self.refreshing = False  # the list is being read
        # a minimum of its own: the filters' rows would otherwise set the window's, which
        # must fit 1280x720 at 2x (tests/gui/test_layout.py); the table and plots shrink
        self.setMinimumSize(1, 1)
        self._update_buttons()

    # ---- the list -----------------------------------------------------------------------
    def refresh(self) -> None:
        """List the runs that match the filters. The catalog is read on a thread (a first
        index of many runs, or one locked by another process for up to 2 s, must not hold
        up the window): ``refreshing`` until the list is shown."""
        if not self.root.is_dir():
            self.entries, self.warnings = [], []
            self._fill()
            self._say(f"no runs yet: {self.root} does not exist")
            return
        try:
            filters = filter_values({key: edit.text() for key, edit in self.filters.items()})
            select_entries([], **filters)  # a bad filter: its one line now, the list kept
        except ConfigError as exc:
            self._say(str(exc), error=True)
            return
        self._list_token += 1
        token, root, self.refreshing = self._list_token, self.root, True

        def work() -> tuple[int, list[str], object]:
            warnings: list[str] = []
            try:
                result: object = find_runs(root, warn=warnings.append, **filters)
            except Exception as exc:  # an unreadable folder: said, the GUI goes on
                result = exc
            return token, warnings, result

        offthread.start(work, self._listed, name="gelrig-runs")

    def _listed(self, found: tuple[int, list[str], object]) -> None:
        token, warnings, result = found
        for line in warnings:  # each said once, even from a list superseded since
            if self.warn is not None:
                self.warn(line)
        if token != self._list_token:
            return
        self.refreshing, self.warnings = False, warnings
        if isinstance(result, BaseException):
            self._say(f"cannot list the runs in {self.root}: {result}", error=True)
            return
        assert isinstance(result, list)
        self.entries = result
        self._fill()
        line = f"{len(result)} run(s) in {self.root}"
        self._say("; ".join([*warnings, line]), error=bool(warnings))

    def _say(self, text: str, error: bool = False) -> None:
        self.status.setText(text)
        self.status.setStyleSheet(_ERROR if error else "")

    def _fill(self) -> None:
        self.table.setRowCount(len(self.entries))
        for row, entry in enumerate(self.entries):
            for col, (_title, key) in enumerate(COLUMNS):
                item = QTableWidgetItem(cell_text(entry, key)[:80])
                item.setToolTip(entry["path"] if key == "name" else cell_text(entry, key))
                self.table.setItem(row, col, item)
        self._update_buttons()

    def selected(self) -> list[dict[str, Any]]:
        """The selected runs' catalog entries, in the list's order."""
        rows = sorted({index.row() for index in self.table.selectionModel().selectedRows()})
        return [self.entries[r] for r in rows if r < len(self.entries)]

    def select(self, names: list[str]) -> None:
        """Select the runs with these folder names (tests, scripts)."""
        self.table.clearSelection()
        mode = self.table.selectionMode()
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.MultiSelection)
        for row, entry in enumerate(self.entries):
            if entry["name"] in names:
                self.table.selectRow(row)
        self.table.setSelectionMode(mode)

    def _update_buttons(self) -> None:
        count = len(self.selected())
        self.open_button.setEnabled(count == 1)
        self.compare_button.setEnabled(count >= 2)

    # ---- open, compare ------------------------------------------------------------------
    def open_selected(self) -> None:
        chosen = self.selected()
        if len(chosen) == 1:
            self.open_run(Path(chosen[0]["path"]))

    def compare_selected(self) -> None:
        """Overlay the selected runs (two or more): their step files are read on a thread
        (a day-long hold is large), then drawn here."""
        chosen = self.selected()
        if len(chosen) < 2:
            self._say("select two runs or more to compare", error=True)
            return
        self._token += 1
        token, self.loading = self._token, True
        self._say(f"reading {len(chosen)} runs…")

        def work() -> tuple[int, list[dict[str, Any]], object]:
            try:
                result: object = [curves_of(entry["path"]) for entry in chosen]
            except Exception as exc:  # a damaged step file: said, the GUI goes on
                result = exc
            return token, chosen, result

        offthread.start(work, self._show, name="gelrig-compare")

    def _show(self, loaded: tuple[int, list[dict[str, Any]], object]) -> None:
        token, chosen, result = loaded
        if token != self._token:
            return  # a newer comparison was asked for
        self.loading = False
        if isinstance(result, BaseException):
            self._say(f"cannot compare: {type(result).__name__}: {result}", error=True)
            return
        assert isinstance(result, list)
        notes = self.compare.show_runs(result, chosen)
        self._say("; ".join(notes) if notes else f"{len(chosen)} runs compared",
                  error=bool(notes))

