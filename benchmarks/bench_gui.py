"""The GUI under load: event-loop latency while 1 kHz force data streams, and memory after a
3000 s hold at 1 kHz has been plotted.

Run: python benchmarks/bench_gui.py [--seconds 8] [--hold 3000]   (offscreen by default)

The main window runs on the built-in simulated compression rig, recording to a temporary
folder, exactly as ``gelrig gui`` does. A 5 ms precise timer measures how late the event loop
serves it (its lateness is the latency a click or a redraw would see). Prints
1. process memory (RSS) with the window up and the rig connected, and after a full paper hold
   (ramp 6 % at 0.002 /s, 3000 s at 1 kHz: 3.0e6 samples) ran as fast as possible and was
   plotted, against the growth of the same run with no GUI (measured in a subprocess), with
   the time of one full-view redraw from scratch;
2. baseline: the latency with the rig connected and idle (the instruments polled at 5 Hz);
3. the latency while a ramp-and-hold streams 1 kHz samples in paced time at 1x (1 kS/s, the
   rate at the rig), at 10x and 100x, and as fast as possible (the plots redraw from growing
   buffers on their own 25 Hz timer). The samples that reached the plots come in the hold's
   2 s blocks, so at 1x their rate over a few seconds is quantised.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QElapsedTimer, QEventLoop, Qt, QTimer
from PySide6.QtWidgets import QApplication

from gelrig.commands.gui import make_services
from gelrig.gui.binding import check_binding
from gelrig.gui.mainwindow import PACES, MainWindow
from gelrig.gui.rundata import RunData

PERIOD_MS = 5


def rss_mb() -> float:
    """Resident set size of this process now (MB)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return math.nan


def pump(app: QApplication, until: Callable[[], bool], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not until():
        if time.monotonic() > deadline:
            raise TimeoutError("the GUI did not get there in time")
        app.processEvents()
        time.sleep(0.002)


def latency(seconds: float) -> tuple[float, float, int]:
    """(median, max) lateness (ms) of a 5 ms timer over ``seconds`` of the real event loop."""
    late: list[float] = []
    clock = QElapsedTimer()
    timer = QTimer()
    timer.setTimerType(Qt.TimerType.PreciseTimer)
    timer.setInterval(PERIOD_MS)
    last = [0]

    def tick() -> None:
        now = clock.nsecsElapsed()
        late.append(max(0.0, (now - last[0]) / 1e6 - PERIOD_MS))
        last[0] = now

    timer.timeout.connect(tick)
    loop = QEventLoop()
    QTimer.singleShot(round(seconds * 1000), loop.quit)
    clock.start()
    timer.start()
    loop.exec()
    timer.stop()
    return statistics.median(late[1:]), max(late[1:]), len(late)


def hold_protocol(hold: float, strain: float, strain_rate: float) -> dict[str, object]:
    return {"protocol": {"name": "bench hold", "rig": "compression"},
            "sample": {"diameter": "18.63 mm"}, "step": [
        {"kind": "ramp_hold", "first_touch": "6.2 mm", "strain": strain,
         "strain_rate": f"{strain_rate} /s", "hold": f"{hold} s", "rate": "1000 Hz",
         "terms": 1}]}


def stream(app: QApplication, window: MainWindow, seconds: float) -> None:
    """Latency while a long hold streams 1 kHz samples at each pace (then abort it)."""
    pace_index = {rate: i for i, (_label, rate) in enumerate(PACES)}
    # Reach the hold as fast as possible, then pace it.
    window.protocol.set_table(hold_protocol(600_000, 0.01, 0.01), "<bench: streaming>")
    window.protocol.run_button.click()
    if not window.desk.running:
        raise SystemExit(f"the run did not start: {window.protocol.why_not}\n"
                         f"{window.log.toPlainText()}")
    data = window.desk.data
    pump(app, lambda: data.samples() > 5000, 60)
    for label, rate in (("1x  (1 kS/s)", 1.0), ("10x (10 kS/s)", 10.0),
                        ("100x (100 kS/s)", 100.0), ("as fast as possible", math.inf)):
        window.pace_box.setCurrentIndex(pace_index[rate])
        before = data.samples()
        med, worst, _ticks = latency(seconds)
        rate_seen = (data.samples() - before) / seconds
        print(f"  streaming 1 kHz data at {label:20s}{med:7.2f} / {worst:7.2f} ms   "
              f"({rate_seen / 1e3:,.1f} kS/s reached the plots)")
    window.desk.abort("benchmark")
    pump(app, lambda: not window.desk.running, 60)


def headless(hold: float) -> None:
    """The same hold with no GUI (for the baseline): RSS before and after, as 'MB MB'."""
    from gelrig.factory import build_rig
    from gelrig.instrument.core.clock import PacedClock
    from gelrig.instrument.core.store import RunDirectory
    from gelrig.protocols.events import EventBus
    from gelrig.protocols.recorder import Recorder
    from gelrig.protocols.rigfile import default_rig, load_rig
    from gelrig.protocols.runner import Runner
    from gelrig.protocols.spec import parse_protocol

    rig = build_rig(load_rig(default_rig("compression")), PacedClock(math.inf))
    before = rss_mb()
    bus = EventBus()
    run = RunDirectory.create(Path(tempfile.mkdtemp(prefix="gelrig-bench-gui-")) / "run", {})
    bus.subscribe(Recorder(run), critical=True)
    Runner(rig, parse_protocol(hold_protocol(hold, 0.06, 0.002)), bus).run()
    gc.collect()
    print(f"{before:.1f} {rss_mb():.1f}")
    rig.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=8.0, help="wall time per measurement")
    parser.add_argument("--hold", type=float, default=3000.0, help="hold for the memory (s)")
    parser.add_argument("--headless", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.headless:
        headless(args.hold)
        return
    out = subprocess.run([sys.executable, __file__, "--headless", "--hold", str(args.hold)],
                         capture_output=True, text=True, check=True).stdout.split()
    headless_growth = float(out[-1]) - float(out[-2])
    app = QApplication(sys.argv[:1])
    check_binding()
    runs = Path(tempfile.mkdtemp(prefix="gelrig-bench-gui-"))
    window = MainWindow(make_services(pace=math.inf, runs=runs))
    window.show()
    window.start()
    pump(app, lambda: window.desk.rig is not None, 30)
    pump(app, lambda: window.instruments.values["force_N"].text() != "-", 10)
    med, worst, ticks = latency(args.seconds)
    rss_idle = rss_mb()

    # Memory after a full paper hold has been plotted.
    window.pace_box.setCurrentIndex(len(PACES) - 1)  # as fast as possible
    window.protocol.set_table(hold_protocol(args.hold, 0.06, 0.002), "<bench: 3000 s hold>")
    t0 = time.perf_counter()
    window.protocol.run_button.click()
    pump(app, lambda: not window.desk.running, 1200)
    wall = time.perf_counter() - t0
    n = window.desk.data.samples()
    t1 = time.perf_counter()
    window.plots.clear()
    window.plots.refresh(window.desk.data)
    window.plots.paint_now()
    redraw = time.perf_counter() - t1
    app.processEvents()
    rss_after = rss_mb()
    print(f"Memory: a {args.hold:g} s hold at 1 kHz ({n / 1e6:.2f}e6 samples, "
          f"{window.protocol.state.value} in {wall:.1f} s wall) plotted")
    print(f"  RSS before (window up, rig connected, idle) {rss_idle:.0f} MB; after "
          f"{rss_after:.0f} MB (+{rss_after - rss_idle:.0f} MB, "
          f"{(rss_after - rss_idle) * 1e6 / max(n, 1):.0f} B per sample)")
    print(f"  baseline: the same run with no GUI (runner, recorder, simulators) +"
          f"{headless_growth:.0f} MB; the GUI's sample buffers hold "
          f"{window.desk.data.nbytes() / 2**20:.0f} MB")
    print(f"  plotted {window.plots.points() / 1e6:.2f}e6 samples; one full-view redraw "
          f"from scratch {redraw * 1e3:.0f} ms")

    window.plots.clear()
    window.desk.data = RunData()
    app.processEvents()
    gc.collect()
    print(f"\nGUI event-loop latency: lateness of a {PERIOD_MS} ms timer "
          f"({args.seconds:g} s each; median / max)")
    print(f"  baseline, rig connected and idle        {med:7.2f} / {worst:7.2f} ms   "
          f"({ticks} ticks)")
    stream(app, window, args.seconds)
    window.close()


if __name__ == "__main__":
    main()
