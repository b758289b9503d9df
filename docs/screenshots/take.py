"""Screenshot of gelrig's main window on a simulated rig, in a real window.

    xvfb-run -a -s "-screen 0 1440x900x24" python docs/screenshots/take.py OUT.png \
        [compression|shear] [idle|running SECONDS|finished|sample]

``running`` starts the rig's paper protocol at 100x and shoots after SECONDS of wall time;
``finished`` runs it as fast as possible and shoots the finished run. Runs go to a
temporary folder. ``sample`` loads the paper protocol, gives a 12 mm sphere in the Sample
fields (a GUI settings file of its own) and shoots once it is rehearsed. Used for the
README's screenshots.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

from PySide6.QtWidgets import QApplication

from gelrig.commands.gui import make_services
from gelrig.gui.mainwindow import MainWindow
from gelrig.protocols.rigfile import default_rig
from gelrig.protocols.spec import paper_protocol


def pumping(app: QApplication) -> Callable[[Callable[[], bool], float], None]:
    """``pump(done, timeout)``: run ``app``'s events until ``done()`` or ``timeout`` s."""

    def pump(done: Callable[[], bool], timeout: float) -> None:
        end = time.monotonic() + timeout
        while not done() and time.monotonic() < end:
            app.processEvents()
            time.sleep(0.01)

    return pump


def main(out: str, kind: str = "compression", mode: str = "idle", seconds: str = "8") -> None:
    app = QApplication(sys.argv[:1])
    pump = pumping(app)

    with tempfile.TemporaryDirectory() as runs:
        os.environ["GELRIG_SETTINGS"] = str(Path(runs) / "gui-settings.ini")  # not the user's
        window = MainWindow(make_services(default_rig(kind), math.inf, Path(runs)))
        window.show()
        window.start()
        pump(lambda: window.desk.rig is not None, 60)
        pump(lambda: False, 1.0)
        if mode == "sample":
            path = paper_protocol(kind)
            window.protocol.set_table(tomllib.loads(path.read_text()), str(path))
            fields = window.protocol.sample_form
            fields.edits["name"].setText("PDMS sphere A3")
            fields.edits["diameter" if kind == "compression" else "r1"].setText("12 mm")
            fields.edits["material"].setText("Sylgard 184, 10:1, cured 2 h at 80 C")
            pump(window.protocol.run_button.isEnabled, 120)
            pump(lambda: window.protocol.rehearsal is not None, 120)
            pump(lambda: False, 1.0)
        elif mode != "idle":
            path = paper_protocol(kind)
            window.protocol.set_table(tomllib.loads(path.read_text()), str(path))
            pump(window.protocol.run_button.isEnabled, 120)
            if mode == "running":
                window.pace_box.setCurrentText("100x")
            window.protocol.run_button.click()
            if mode == "running":
                pump(lambda: False, float(seconds))
            else:
                pump(lambda: not window.desk.running, 900)
                pump(lambda: False, 1.0)
        window.grab().save(out)
        if window.desk.running:
            window.desk.abort("screenshot taken")
            pump(lambda: not window.desk.running, 60)
        window.close()


if __name__ == "__main__":
    main(*sys.argv[1:])
