"""Run by test_layout in a subprocess (QT_SCALE_FACTOR and the screen are set before Qt
starts): open the main window on the simulated compression rig and print, as one JSON line,
the screen and window sizes and where STOP and the status bar lie inside the window."""

import json
import math
import sys
import time
from pathlib import Path

from PySide6.QtCore import QPoint
from PySide6.QtWidgets import QApplication

from gelrig.commands.gui import make_services
from gui.mainwindow import MainWindow


def main() -> None:
    app = QApplication(sys.argv[:1])
    window = MainWindow(make_services(pace=math.inf, runs=Path(sys.argv[1])))
    window.show()
    window.start()
    deadline = time.monotonic() + 30
    while window.session.rig is None and time.monotonic() < deadline:
        app.processEvents()
        time.sleep(0.01)
    for _ in range(20):
        app.processEvents()
    screen = window.screen().availableGeometry()
    probe = {"screen": [screen.width(), screen.height()],
             "window": [window.width(), window.height()]}
    for name, widget in (("stop", window.stop_button), ("status", window.statusBar())):
        corner = widget.mapTo(window, QPoint(0, 0))
        probe[name] = [corner.x(), corner.y(), widget.width(), widget.height()]
        probe[f"{name}_visible"] = widget.isVisible() and not widget.visibleRegion().isEmpty()
    print(json.dumps(probe))
    window.close()


if __name__ == "__main__":
    main()
