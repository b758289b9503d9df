"""Run by test_layout in a subprocess (QT_SCALE_FACTOR and the screen are set before Qt
starts): open the main window on the simulated compression rig and print, as one JSON line,
the screen and window sizes and where STOP and the status bar lie inside the window, into the
file named by the second argument (stdout carries whatever else Qt or the run prints)."""

import json
import math
import sys
import time
from pathlib import Path

from PySide6.QtCore import QPoint
from PySide6.QtWidgets import QApplication

from gelrig.commands.gui import make_services
from gelrig.gui.mainwindow import MainWindow
from tests.gui.test_app import short_compression


def connected() -> tuple[QApplication, MainWindow]:
    """The application and its shown window, connected to the simulated compression rig
    (runs under the folder named by the first argument)."""
    app = QApplication(sys.argv[:1])
    window = MainWindow(make_services(pace=math.inf, runs=Path(sys.argv[1])))
    window.show()
    window.start()
    deadline = time.monotonic() + 30
    while window.desk.rig is None and time.monotonic() < deadline:
        app.processEvents()
        time.sleep(0.01)
    return app, window


def done(window: MainWindow, probe: dict[str, object]) -> None:
    """Write ``probe`` to the file named by the second argument; close the window."""
    Path(sys.argv[2]).write_text(json.dumps(probe))
    window._leave_loaded = True
    window.close()


def main() -> None:
    app, window = connected()
    for _ in range(20):
        app.processEvents()
    screen = window.screen().availableGeometry()
    probe = {"screen": [screen.width(), screen.height()],
             "window": [window.width(), window.height()]}
    for name, widget in (("stop", window.stop_button), ("status", window.statusBar())):
        corner = widget.mapTo(window, QPoint(0, 0))
        probe[name] = [corner.x(), corner.y(), widget.width(), widget.height()]
        probe[f"{name}_visible"] = widget.isVisible() and not widget.visibleRegion().isEmpty()
    # Open run on a short finished run: it fits too (resizable, within the screen)
    window.protocol.set_table(short_compression(), "<probe>")
    window.protocol.run_button.click()
    deadline = time.monotonic() + 90
    while (window.desk.running or window.desk.run_path is None) \
            and time.monotonic() < deadline:
        app.processEvents()
        time.sleep(0.01)
    viewer = window.open_run(window.desk.run_path)
    for _ in range(20):
        app.processEvents()
    if viewer is not None:
        frame = viewer.frameGeometry()
        probe["run_window"] = [frame.x(), frame.y(), frame.width(), frame.height()]
        probe["run_window_min"] = [viewer.minimumSizeHint().width(),
                                   viewer.minimumSizeHint().height()]
        viewer.close()
    done(window, probe)


if __name__ == "__main__":
    main()
