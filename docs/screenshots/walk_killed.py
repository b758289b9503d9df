"""The walk of issue 25 in a real window: an instrument served as its own process
(``gelrig sim serve usb6001``: the compression rig's force input; or ``kdc101``, ``mcr501``)
and killed, once while idle and once while a run goes; the whole screen is shot 3 s later
(``import -window root``), as a person at the rig sees it.

    Xvfb :99 -screen 0 1280x720x24 & DISPLAY=:99 openbox &
    DISPLAY=:99 PYTHONPATH=. python docs/screenshots/walk_killed.py docs/screenshots [usb6001]

writes ``killed-idle.png`` and ``killed-running.png`` (with a third argument, a suffix:
``killed-idle-2x.png``) and prints the banner's text of each.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from PySide6.QtWidgets import QApplication

from gelrig.commands.gui import make_services
from gelrig.gui.mainwindow import MainWindow
from tests.frozen_runs import served_rig

#: Seconds between the kill and the screenshot.
AFTER_KILL = 3.0


def main(out: str, instrument: str = "usb6001", suffix: str = "") -> None:
    app = QApplication(sys.argv[:1])
    folder = Path(out)

    def pump(done: Callable[[], bool], timeout: float) -> None:
        end = time.monotonic() + timeout
        while not done() and time.monotonic() < end:
            app.processEvents()
            time.sleep(0.01)

    for mode in ("idle", "running"):
        with tempfile.TemporaryDirectory() as tmp, \
                served_rig(instrument, Path(tmp)) as (rig, protocol, served, _proxy):
            window = MainWindow(make_services(rig, 1.0, Path(tmp) / "runs"))
            window.show()
            window.start()
            pump(lambda w=window: "now: " in w.banner.text(), 60)
            if mode == "running":
                window.protocol.load_file(protocol)
                pump(window.protocol.run_button.isEnabled, 60)
                window.protocol.run_button.click()
                pump(lambda w=window: w.desk.data.samples() > 0, 60)
                pump(lambda: False, 1.0)
            served.kill()
            pump(lambda: False, AFTER_KILL)
            shot = folder / f"killed-{mode}{suffix}.png"
            subprocess.run(["import", "-window", "root", str(shot)], check=True)
            print(f"{shot}: {window.banner.text()}")
            print(f"  status bar: {window.safety_label.full}")
            if window.desk.running:
                window.desk.abort("walk done")
                pump(lambda w=window: not w.desk.running, 60)
            window._leave_loaded = True
            window.close()
            pump(lambda: False, 0.5)


if __name__ == "__main__":
    main(*sys.argv[1:])
