"""Memory of the GUI over consecutive runs: RSS after each of ten compression runs against the
idle figure (issue 15: 290 MB idle grew to 1.1 GB after six runs).

Run: python benchmarks/bench_gui_memory.py [--runs 10] [--hold 3000]   (offscreen by default)

The main window runs on the built-in simulated compression rig at pace "as fast as possible"
(virtual time), recording to a temporary folder, exactly as ``gelrig gui`` does; each run is
the paper's compression protocol (contact search, 6 % ramp, a hold at 1 kHz: 3.0e6 samples
for 3000 s), started with the Run button after the previous one finished, its plots drawn.
Prints the idle RSS, then after each run the RSS and its growth over idle, and the median
growth over the last half of the runs (the steady state; target: within 300 MB of idle).
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from bench_gui import pump, rss_mb
from PySide6.QtWidgets import QApplication

from gelrig.commands.gui import make_services
from gelrig.gui.binding import check_binding
from gelrig.gui.mainwindow import PACES, MainWindow
from gelrig.protocols.spec import paper_protocol

#: The issue's target: the GUI stays within this much of its idle RSS (MB).
TARGET_MB = 300.0


def settle(app: QApplication) -> float:
    """RSS once pending deletions ran and the collector did (MB)."""
    for _ in range(5):
        app.processEvents()
    gc.collect()
    app.processEvents()
    return rss_mb()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10, help="consecutive runs")
    parser.add_argument("--hold", type=float, default=3000.0, help="hold of each run (s)")
    args = parser.parse_args()
    app = QApplication(sys.argv[:1])
    check_binding()
    runs = Path(tempfile.mkdtemp(prefix="gelrig-bench-gui-memory-"))
    window = MainWindow(make_services(pace=math.inf, runs=runs))
    window.show()
    window.start()
    pump(app, lambda: window.desk.rig is not None, 30)
    window.pace_box.setCurrentIndex(len(PACES) - 1)
    pump(app, lambda: window.instruments.values["force_N"].text() != "-", 10)
    idle = settle(app)
    print(f"GUI memory over {args.runs} consecutive compression runs (paper protocol, "
          f"{args.hold:g} s hold at 1 kHz, pace inf, simulated rig, offscreen)")
    print(f"  idle (window up, rig connected): {idle:.0f} MB")
    path = paper_protocol("compression")
    import tomllib

    table = tomllib.loads(path.read_text())
    table["step"][1]["hold"] = f"{args.hold:g} s"
    growth: list[float] = []
    for k in range(args.runs):
        window.protocol.set_table(table, str(path))
        pump(app, lambda: window.protocol.run_button.isEnabled(), 120)
        t0 = time.perf_counter()
        window.protocol.run_button.click()
        if not window.desk.running:
            raise SystemExit(f"run {k + 1} did not start: {window.protocol.why_not}\n"
                             f"{window.log.toPlainText()[-2000:]}")
        pump(app, lambda: not window.desk.running, 1800)
        wall = time.perf_counter() - t0
        pump(app, lambda: window.protocol.state.finished, 30)
        rss = settle(app)
        growth.append(rss - idle)
        print(f"  after run {k + 1:2d} ({window.protocol.state.value}, "
              f"{window.desk.data.samples() / 1e6:.2f}e6 samples, {wall:5.1f} s wall): "
              f"{rss:6.0f} MB  (+{rss - idle:4.0f} MB over idle)", flush=True)
    tail = growth[len(growth) // 2:]
    steady = statistics.median(tail)
    print(f"  steady growth over idle (median of runs {len(growth) - len(tail) + 1}-"
          f"{len(growth)}): +{steady:.0f} MB; ratio to the {TARGET_MB:.0f} MB target "
          f"{steady / TARGET_MB:.2f}; max +{max(growth):.0f} MB")
    window.close()
    app.processEvents()


if __name__ == "__main__":
    main()
