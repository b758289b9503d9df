"""Screenshots of the Results tab and the Queue tab (issue 28) in a real window.

    xvfb-run -a -s "-screen 0 1440x900x24" python docs/screenshots/take_browser.py \
        results OUT.png
    xvfb-run -a -s "-screen 0 1440x900x24" python docs/screenshots/take_browser.py \
        queue OUT.png

``results`` records three short compression runs of three samples (two operators) into a
temporary runs folder with ``gelrig run``, lists them in the Results tab and overlays two.
``queue`` queues a sweep of the hold (2 s, 2 s, 60 s, 60 s) at 10x and shoots while the
third runs: two completed, one running, one waiting.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from pathlib import Path

from PySide6.QtWidgets import QApplication

from gelrig.cli import main as gelrig
from gelrig.commands.gui import make_services
from gelrig.gui.mainwindow import MainWindow
from gelrig.gui.tomlout import dumps
from gelrig.protocols.rigfile import default_rig

sys.path.insert(0, str(Path(__file__).parent))
from take import pumping

HOLD = {"protocol": {"name": "ramp and hold", "rig": "compression"},
        "sample": {"name": "gel", "diameter": "18.63 mm"}, "step": [
            {"kind": "compression_contact_search", "start": "5 mm", "confirm": 0,
             "tare_time": "0.2 s"},
            {"kind": "ramp_hold", "strain": 0.01, "strain_rate": "0.01 /s", "hold": "20 s",
             "rate": "200 Hz", "retract": "0.5 mm", "terms": 1}]}
#: sample, operator, tag, strain of each run of ``results``
RUNS = (("gel-A1", "ada", "week48", 0.01), ("gel-B2", "bo", "week48", 0.02),
        ("gel-C3", "ada", "cure2h", 0.015))


def main(mode: str, out: str) -> None:
    pump = pumping(QApplication(sys.argv[:1]))

    with tempfile.TemporaryDirectory() as home:
        os.environ["GELRIG_SETTINGS"] = str(Path(home) / "gui-settings.ini")  # not the user's
        runs = Path(home) / "runs"
        protocol = Path(home) / "hold.toml"
        protocol.write_text(dumps(HOLD))
        if mode == "results":
            for sample, operator, tag, strain in RUNS:
                HOLD["step"][1]["strain"] = strain
                protocol.write_text(dumps(HOLD))
                assert gelrig(["run", str(protocol), "--no-rehearse", "--sample", sample,
                               "--operator", operator, "--tag", tag,
                               "--out", str(runs / f"20261127-{sample}-compression")]) == 0
        pace = math.inf if mode == "results" else 10.0
        window = MainWindow(make_services(default_rig("compression"), pace, runs))
        window.show()
        window.start()
        pump(lambda: window.desk.rig is not None, 60)
        window.right_split.setSizes([800, 70])  # the log pane short: the tab is the subject
        if mode == "results":
            window.plot_tabs.setCurrentWidget(window.results_tab)
            pump(lambda: not window.results.refreshing, 60)
            window.results.select([e["name"] for e in window.results.entries[:2]])
            window.results.compare_button.click()
            pump(lambda: not window.results.loading, 60)
        else:
            window.protocol.load_file(protocol)
            window.protocol.info_form.set_texts({"operator": "ada", "tags": "week48, sweep"})
            window.left_tabs.setCurrentIndex(3)
            window.queue.param.setText("step[1].hold")
            window.queue.values.setText("2 s; 2 s; 60 s; 60 s")
            window.queue.add_current()
            window.queue.start_button.click()
            pump(lambda: sum(i.state == "completed" for i in window.queue_runner.items) >= 2,
                 300)
            pump(lambda: window.desk.running, 120)
            pump(lambda: False, 3.0)
        pump(lambda: False, 1.5)
        if mode == "results":  # the table at the results, past the runs' fields (laid out)
            table = window.results.compare.table
            table.scrollToItem(table.item(min(5, table.rowCount() - 1), 0),
                               table.ScrollHint.PositionAtTop)
            pump(lambda: False, 0.3)
        window.grab().save(out)
        window.queue_runner.stop()
        if window.desk.running:
            window.desk.abort("screenshot taken")
            pump(lambda: not window.desk.running, 60)
        window._leave_loaded = True
        window.close()


if __name__ == "__main__":
    main(*sys.argv[1:])
