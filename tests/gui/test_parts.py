"""The GUI's pure parts: buffers, decimation, ETA, plan checks, text at the edges."""

import math
import threading

import numpy as np
import pytest

from gelrig.gui.decimate import PeakDecimator
from gelrig.gui.fmt import entry_text, entry_value, quantity
from gelrig.gui.rundata import Columns, RunData
from gelrig.instrument.core.units import lab_time
from gelrig.protocols.events import Progress
from gelrig.protocols.plan import dry_run
from gelrig.protocols.rig import CompressionLimits
from gelrig.protocols.spec import parse_protocol


def protocol(strain=0.01, hold="20 s"):
    return parse_protocol({"protocol": {"name": "t", "rig": "compression"}, "step": [
        {"kind": "compression_contact_search", "start": "5 mm"},
        {"kind": "ramp_hold", "diameter": "18.63 mm", "strain": strain, "hold": hold}]})


def test_columns_grow_and_earlier_views_stay_valid():
    cols = Columns(("t_s", "force_N"))
    cols.append({"t_s": np.arange(3.0), "force_N": np.ones(3)})
    early = cols.views()
    for k in range(100):  # forces several reallocations
        cols.append({"t_s": np.full(100, k + 3.0), "force_N": np.zeros(100)})
    assert cols.n == 10_003
    np.testing.assert_array_equal(early["t_s"], [0.0, 1.0, 2.0])
    assert cols.views()["t_s"][-1] == 102.0
    assert cols.views(10_000)["force_N"].size == 3


def test_run_data_keeps_plotted_columns_and_readers_never_see_a_torn_block():
    data = RunData()
    data.begin_step(0, "hold", "ramp_hold",
                    {"t_s": "s", "force_N": "N", "position_m": "m", "over_range": "1"})
    blocks, size = 400, 50

    def writer():  # the runner's thread: one writer
        for k in range(blocks):
            rows = np.arange(k * size, (k + 1) * size, dtype=float)
            data.append(0, {"t_s": rows, "force_N": -rows, "position_m": 2 * rows,
                            "over_range": np.zeros(size)})

    thread = threading.Thread(target=writer)
    thread.start()
    seen = 0
    while thread.is_alive() or seen < blocks * size:
        (_step, cols), = data.steps()
        n = cols["t_s"].size
        assert n % size == 0 and n >= seen  # whole blocks, never going back
        np.testing.assert_array_equal(cols["t_s"], np.arange(n))  # every row as written
        np.testing.assert_array_equal(cols["force_N"], -cols["t_s"])
        seen = n
    thread.join()
    (step, cols), = data.steps()
    assert step.kind == "ramp_hold"
    assert set(cols) == {"t_s", "force_N", "position_m"}  # over_range is not plotted
    assert data.samples() == blocks * size
    assert data.latest()["position_m"] == 2 * (blocks * size - 1)


def test_peak_decimator_bounds_points_and_keeps_every_extreme():
    rng = np.random.default_rng(1)
    n = 1_000_000
    x = np.cumsum(rng.normal(size=n))
    y = rng.normal(size=n)
    y[123_457] = 50.0  # a spike that must survive decimation
    y[876_543] = -50.0
    dec = PeakDecimator(cap=20_000)
    for end in (10, 5_000, 400_000, n):  # data that grows
        xs, ys = dec.update(x[:end], y[:end])
    assert xs.size <= 20_000 + dec.stride
    assert ys.max() == 50.0 and ys.min() == -50.0
    assert xs[np.argmax(ys)] == x[123_457]
    small = PeakDecimator(cap=100)
    xs, ys = small.update(x[:40], y[:40])
    np.testing.assert_array_equal(ys, y[:40])  # nothing to decimate: every sample


def test_plan_gives_durations_and_fails_checks_over_the_limits():
    plan = dry_run(protocol(), CompressionLimits())
    assert len(plan.durations) == 2 and not plan.failed
    assert plan.durations[1] > 20.0
    assert "limit checks all passed" in plan.text()
    deep = dry_run(protocol(strain=0.2), CompressionLimits())  # 3.7 mm > 2.5 mm overlap
    assert deep.failed and "overlap" in deep.failed[0]


def test_eta_adds_later_steps_to_what_is_left_of_this_one():
    from gelrig.gui.protocol_panel import eta

    plan = dry_run(protocol(hold="100 s"), CompressionLimits())
    d0, d1 = plan.durations
    fraction, left = eta(plan, Progress(0.0, 1, 0.5, 50.0, 40.0, "hold"))
    assert left == pytest.approx(40.0)
    assert fraction == pytest.approx((d0 + 0.5 * d1) / (d0 + d1))
    fraction, left = eta(plan, Progress(0.0, 0, 0.25, 0.0, 0.0, "approach"))
    assert left == pytest.approx(0.75 * d0 + d1)


def test_text_at_the_edges():
    assert quantity(0.0062, "m") == "6.2 mm"
    assert quantity(4.1e-3, "N") == "4.1 mN"
    assert quantity(0.0, "N") == "0 N"
    assert quantity(1413.0, "s") == "1413 s"
    assert lab_time(3725) == "1 h 02 min" and lab_time(math.inf) == "?"
    assert entry_value("2") == 2 and entry_value("0.5") == 0.5
    assert entry_value(" 0.3 mm/s ") == "0.3 mm/s"
    assert entry_text(["1e-4 m/s", 2e-4]) == "1e-4 m/s, 0.0002"


def test_pace_option_of_gelrig_gui():
    import argparse

    from gelrig.commands.gui import pace

    assert pace("1") == 1.0 and pace("10x") == 10.0 and pace("100") == 100.0
    assert math.isinf(pace("inf")) and math.isinf(pace("max"))
    for bad in ("0", "-1", "fast"):
        with pytest.raises(argparse.ArgumentTypeError):
            pace(bad)


def test_stored_fits_say_when_a_second_term_is_not_resolved():
    """ADR 0261: the 2-term entry holds the resolved 1-term values; it is shown as not
    resolved with its reason and no values, never as a 2-term result."""
    from gelrig.gui.runview import stored_summary

    fits = [{"G_e": 7146.0, "relax": [{"G": 625.0, "tau": 1413.0}], "terms_resolved": 1,
             "resolved": True},
            {"G_e": 7146.0, "relax": [{"G": 625.0, "tau": 1413.0}], "terms_resolved": 1,
             "resolved": False,
             "not_resolved": "second term not resolved: BIC improvement -20 < 10"}]
    meta = {"steps": [{"index": 1, "name": "ramp and hold", "results": {"fits": fits}}]}
    lines = [line.strip() for line in stored_summary(meta).splitlines() if "fit" in line]
    assert lines == ["1-term fit: G_e 7.15 kPa, G_1 625 Pa, tau_1 1413 s",
                     "2-term fit: not resolved: second term not resolved: "
                     "BIC improvement -20 < 10"]


def test_an_older_run_json_without_resolved_is_judged_by_its_term_count():
    from gelrig.gui.runview import stored_summary

    fits = [{"G_e": 7146.0, "relax": [{"G": 625.0, "tau": 1413.0}], "terms_resolved": 1},
            {"G_e": 7146.0, "relax": [{"G": 625.0, "tau": 1413.0}], "terms_resolved": 1}]
    meta = {"steps": [{"index": 1, "name": "ramp and hold", "results": {"fits": fits}}]}
    lines = [line.strip() for line in stored_summary(meta).splitlines() if "fit" in line]
    assert lines[0].startswith("1-term fit: G_e 7.15 kPa, G_1 625 Pa")
    assert lines[1] == "2-term fit: not resolved: not every term is resolved"
    assert "625" not in lines[1]


def test_a_term_the_data_do_not_resolve_is_not_shown_as_a_result():
    from gelrig.gui.runview import stored_summary

    fit = {"G_e": 7840.0, "relax": [{"G": 46.7, "tau": 114.0}], "terms_resolved": 0,
           "not_resolved": "first term not resolved: BIC improvement -5.94 < 10"}
    meta = {"steps": [{"index": 1, "name": "ramp and hold", "results": {"fits": [fit]}}]}
    (line,) = [x.strip() for x in stored_summary(meta).splitlines() if "fit" in x]
    assert line == "1-term fit: not resolved: first term not resolved: BIC improvement -5.94 < 10"
    assert "7.84" not in line and "46.7" not in line


@pytest.mark.parametrize("pace, wall", [(1.0, ""), (10.0, " at 10x)"), (math.inf, "fast as")])
def test_the_progress_line_numbers_steps_once_and_states_the_wall_time_only_when_it_differs(
        qtbot, pace, wall):
    from gelrig.gui.protocol_panel import ProtocolPanel

    panel = ProtocolPanel()
    qtbot.addWidget(panel)
    panel.set_rig("compression", CompressionLimits(), connected=True)
    panel.set_table(protocol(hold="100 s").table, "<test>")
    panel.set_pace(pace, real_time=False)
    panel.show_progress(Progress(0.0, 1, 0.5, 50.0, 40.0, "hold"), "ramp and hold")
    text = panel.status.text()
    assert text.startswith("step 1 ramp and hold (steps 0–1): hold — ETA ")
    assert " of 0" not in text  # one numbering: the run's index, never 'step 1 of 0-1'
    if wall:
        assert wall in text
    else:  # at 1x lab time is wall time: no second figure
        assert text.endswith("lab time") and "≈" not in text


@pytest.mark.parametrize("kind", ["compression", "shear"])
def test_manual_rows_keep_their_height_and_the_tare_time_says_what_it_is(qtbot, kind):
    from gelrig.gui.manual import ManualPanel

    panel = ManualPanel()
    qtbot.addWidget(panel)
    panel.set_kind(kind)
    panel.resize(400, 1400)  # far taller than the rows need
    panel.show()
    qtbot.waitExposed(panel)
    lowest = max(b.mapTo(panel, b.rect().bottomLeft()).y() for b in panel.buttons.values())
    assert lowest < 0.4 * panel.height()  # the rows stay together at the top
    if kind == "compression":
        assert panel.entries["tare"].text().startswith("average over ")
        assert panel.entries["tare"].value() == pytest.approx(1.0)
