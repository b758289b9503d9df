"""A shown window settles: its plots never repaint for ever (issue 25).

After a disconnect and reconnect the live manual-control plot got readouts on the new rig's
clock, so its time went back; pyqtgraph's auto-range then took its bounds from the
auto-downsampled (displayed) data, which depend on the range: the range changed the
downsampling, which changed the bounds, ... each paint scheduled the next, processEvents
never returned, and no timer or click (STOP) was served again. These tests show the plots,
feed them as the rig did, and check that a timer is served within a bound; the thread
timeout ends the session if a paint loop never yields (a signal cannot break one)."""

import time

import numpy as np
import pytest
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from gelrig.gui.plots import CompressionPlots, IdlePlots, configure
from gelrig.gui.rundata import RunData

#: A timer of 50 ms must be served within this (s), on a busy shared machine.
SERVED_WITHIN = 5.0


def served(timeout: float = SERVED_WITHIN) -> float:
    """Seconds until a 50 ms single-shot timer fires while events are processed; inf if it
    did not within ``timeout`` (each processEvents returned, but the timer starved)."""
    fired: list[float] = []
    QTimer.singleShot(50, lambda: fired.append(time.monotonic()))
    start = time.monotonic()
    while not fired and time.monotonic() - start < timeout:
        QApplication.processEvents()
    return fired[0] - start if fired else float("inf")


def range_changes(plots: list, seconds: float = 0.5) -> int:
    """How often the plots' views change range in ``seconds`` with no new data, once the
    first layout and paints are done (``seconds`` of events first)."""
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        QApplication.processEvents()
    count = [0]
    for plot in plots:
        plot.getPlotItem().getViewBox().sigRangeChanged.connect(
            lambda *_: count.__setitem__(0, count[0] + 1))
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        QApplication.processEvents()
    return count[0]


@pytest.mark.timeout(60, method="thread")
@pytest.mark.parametrize("before, after", [(1000, 5), (1000, 1), (3000, 20), (6000, 0)])
def test_the_manual_plot_settles_when_a_reconnected_rig_restarts_its_clock(
        qtbot, before, after):
    configure()
    idle = IdlePlots()
    qtbot.addWidget(idle)
    idle.resize(800, 500)
    idle.show()
    qtbot.waitExposed(idle)
    rng = np.random.default_rng(before + after)
    for clock in (before, after):  # the first rig's readouts, then the reconnected one's
        for k in range(1, clock + 1):
            idle.add({"t_s": 0.2 * k, "force_N": 0.01 * rng.random(),
                      "position_m": 5e-3 + 1e-9 * k})
    assert served() < SERVED_WITHIN
    assert range_changes(list(idle.plots.values())) == 0  # settled: no paint loop
    times = np.fromiter(idle.t, float)
    assert np.all(np.diff(times) > 0)  # the time axis only increases
    if after:
        assert idle.points() == after  # restarted on the new clock


@pytest.mark.timeout(60, method="thread")
def test_the_run_plots_settle_at_every_width(qtbot):
    """Auto-downsampling of the force-time curve near a whole factor, at many widths."""
    configure()
    plots = CompressionPlots()
    qtbot.addWidget(plots)
    plots.show()
    data = RunData()
    data.begin_step(0, "ramp and hold", "ramp_hold",
                    {"t_s": "s", "force_N": "N", "position_m": "m"})
    t = np.linspace(0.0, 500.0, 20_001)
    data.append(0, {"t_s": t, "force_N": 1e-3 * np.sin(t), "position_m": 5e-3 - 1e-6 * t})
    plots.refresh(data)
    for width in range(300, 1300, 97):
        plots.resize(width, 400)
        assert served() < SERVED_WITHIN, width
    assert range_changes(plots.plots) == 0


def test_auto_range_takes_all_the_data_not_what_is_drawn(qtbot):
    from gelrig.gui.plots import Curve

    configure()
    curve = Curve()
    x = np.array([0.0, 5.0, 1.0, np.nan, 3.0])  # not increasing, with a gap
    curve.setData(x, np.array([2.0, -1.0, np.inf, 4.0, 0.5]))
    assert curve.dataBounds(0) == (0.0, 5.0)
    assert curve.dataBounds(1) == (-1.0, 4.0)
    curve.setData(np.array([]), np.array([]))
    assert curve.dataBounds(0) == (None, None)
