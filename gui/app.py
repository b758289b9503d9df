"""Entry of the Qt application: one QApplication, one main window, the services passed in."""

from __future__ import annotations

import sys

from PySide6.QtWidgets import QApplication

from gelrig.gui.binding import check_binding
from gelrig.gui.mainwindow import MainWindow
from gelrig.gui.services import Services


def run_app(services: Services, argv: list[str] | None = None) -> int:
    """Show the main window on the services' rig and run the event loop; the exit code."""
    check_binding()
    app = QApplication.instance() or QApplication(argv if argv is not None else sys.argv[:1])
    window = MainWindow(services)
    window.show()
    window.start()
    return app.exec()
