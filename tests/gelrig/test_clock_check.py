"""Clock invariance (issue 24): the same protocol on virtual, paced and real time records the
same contact, through the whole simulated rig (simulator, wire, driver, runner, recorder),
with the instruments' timing switched on (the USB-6001's documented drift, USB transfers,
latency and jitter; a KDC101 reply latency).

The rig's force noise is 0.05 mN (the paper's rig: 0.2 mN): with the paper's noise, two runs
of the contact search differ by about 1.6 um rms even on one clock (the noise falls on other
samples), which would hide what the clocks do; 0.05 mN makes the residual criterion 2x
stricter in newtons (the recorded noise, with the ADC's quantization, is 0.10 mN).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from gelrig.clock_check import ClockRun, record_short_run, timing_rig

NOISE = "0.05 mN"


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return timing_rig(tmp_path_factory.mktemp("rig"), noise=NOISE)


@pytest.fixture(scope="module")
def virtual(rig: Path, tmp_path_factory: pytest.TempPathFactory) -> ClockRun:
    return record_short_run(tmp_path_factory.mktemp("virtual"), "virtual", rig=rig)


def check_same_contact(run: ClockRun, ref: ClockRun) -> None:
    # what the run's own time base says it cannot know: its force samples' start (run.json),
    # at the contact search's 0.3 mm/s (a loaded machine's real clock: a few ms)
    start = run.time_base["force"]["uncertainty_s"]
    search_bound = 2e-6 + 0.3e-3 * start
    search_shift = run.search_touch - ref.search_touch
    assert abs(search_shift) <= search_bound, "contact search's first touch"
    # the 1 um; on the real clock the samples fall elsewhere on the ramp, so the
    # refit draws other noise: there, 3 of the two runs' own standard errors combined
    se = math.hypot(run.ramp_touch_se, ref.ramp_touch_se)
    ramp_bound = max(1e-6, 3 * se) if run.clock == "real" else 1e-6
    ramp_shift = run.ramp_touch - ref.ramp_touch
    assert abs(ramp_shift) <= ramp_bound, \
        ("first touch refitted on the ramp", run.ramp_touch_se, ref.ramp_touch_se)
    # The measured depth is the hold position (search touch + depth) less the ramp's refitted
    # touch: it carries both touches' shifts and nothing else (the stage ends where it was sent)
    depth_shift = run.depth - ref.depth
    assert abs(depth_shift - (search_shift - ramp_shift)) <= 0.2e-6, "hold position"
    # so its bound is the issue's 0.5 %, or the two touches' bounds where those are wider (the
    # real clock's 3 s.e.: CI saw 0.56 %, a ramp touch 1.9 um and a search touch 1.3 um off)
    assert abs(depth_shift) <= max(0.005 * ref.depth, search_bound + ramp_bound), \
        "measured depth"
    # the recorded force is the contact model's at the recorded plate position
    assert run.residual_rms <= 1.5 * run.noise
    assert run.flagged <= 0.01 * run.t.size
    # the residual's course over the hold is the ADC's (the noise is below a code), within
    # the noise of each bin's mean
    assert run.hold_drift_adc <= run.noise * (0.05 + 3 / math.sqrt(run.hold_bin_samples))


def test_virtual_run_records_the_contact_model(virtual: ClockRun) -> None:
    assert virtual.flagged == 0
    assert 0 < virtual.ramp_touch_se < 1e-6  # the refit states its own noise
    assert virtual.residual_rms <= 1.5 * virtual.noise
    assert abs(virtual.ramp_touch - 6.2e-3) <= 2e-6  # the truth's first touch


def test_the_residuals_course_over_the_hold_is_the_adcs_codes(virtual: ClockRun) -> None:
    """Issue 24, item 5: over the 60 s hold the force relaxes by 0.25 mN, less than one
    14-bit code (0.3 mN), and with 0.05 mN of noise the mean of the codes is not the force:
    the binned residual moves by about 0.4 of the noise rms on every clock. The quantiser's
    expected bias (no fitted parameter) accounts for it."""
    assert virtual.hold_drift > 0.2 * virtual.noise  # there is a course to explain
    assert virtual.hold_bin_samples >= 400  # 500 samples a bin: 0.045 noise rms a mean
    assert virtual.hold_drift_adc <= 0.15 * virtual.noise
    assert virtual.hold_drift_adc <= 0.3 * virtual.hold_drift


def test_run_json_states_each_instruments_time_mapping(virtual: ClockRun) -> None:
    force, stage = virtual.time_base["force"], virtual.time_base["stage"]
    assert force["method"].startswith("sample clock") and force["uncertainty_s"] is not None
    assert force["details"]["drift_ppm"] == pytest.approx(100.0, abs=20.0)  # the twin's
    assert "commanded motion" in stage["method"]
    assert stage["details"]["disagreements"] == 0
    assert stage["details"]["report_window_max_s"] is not None


@pytest.mark.parametrize("clock", ["paced:20", "paced:100"])
def test_paced_runs_record_what_the_virtual_run_records(
        clock: str, rig: Path, virtual: ClockRun, tmp_path: Path) -> None:
    check_same_contact(record_short_run(tmp_path, clock, rig=rig), virtual)


def test_real_time_records_what_virtual_time_records(rig: Path, tmp_path: Path) -> None:
    """Short: one confirming approach, a 3 % ramp at the paper's 0.002 /s and a 2 s hold:
    about 45 s of real time."""
    short = {"hold": "2 s", "confirm": 1, "strain": 0.03, "rig": rig}
    ref = record_short_run(tmp_path / "virtual", "virtual", **short)  # type: ignore[arg-type]
    check_same_contact(record_short_run(tmp_path / "real", "real", **short),  # type: ignore[arg-type]
                       ref)


def test_status_updates_report_the_stage_at_its_own_rate_at_any_pace(
        tmp_path: Path, virtual: ClockRun) -> None:
    """With the KDC101's status updates taken as reports (issue 24, item 3), the stage is
    reported every 100 ms of lab time (the twin's period) within a window of about 20 ms
    at paced:20 and at paced:100 alike, though the host reads it only when a USB transfer of
    force samples comes (every 0.32 s): the position's resolution in lab time does not
    depend on the pace."""
    rig = timing_rig(tmp_path / "rig", noise=NOISE, updates=True)
    stats = {}
    for clock in ("paced:20", "paced:100"):
        run = record_short_run(tmp_path / clock.replace(":", "_"), clock, hold="5 s",
                               confirm=1, rig=rig)
        d = run.time_base["stage"]["details"]
        assert d["update_interval_median_s"] == pytest.approx(0.1, rel=1e-3)
        # the window opens a link latency (16 ms, StageConfig's) before the input was empty;
        # the host's own delays add: medians 18-25 ms alone, 27 ms beside a test suite, all
        # far inside the 0.32 s between reads without the updates
        assert d["update_window_median_s"] < 0.016 + 0.025
        stats[clock] = d
        assert run.residual_rms <= 1.5 * run.noise
        assert run.flagged <= 0.01 * run.t.size
        assert abs(run.search_touch - virtual.search_touch) <= 3e-6
    slow, fast = stats["paced:20"], stats["paced:100"]
    assert abs(slow["update_window_median_s"] - fast["update_window_median_s"]) <= 0.010
    assert fast["updates_kept"] == pytest.approx(slow["updates_kept"], rel=0.1)


#: paced:100 less virtual over 6 seeds (benchmarks/bench_shear_clocks.py --seeds 1,2,3,4,5,6,
#: 2x2 ladder): the standard deviation of the difference, for the touch gap (m) and, at the
#: first overlap, per speed, l_g, l_c/l_g and mu (relative). Their means were within one
#: standard error of 0: the differences are the noise, drawn at other instants.
LADDER_DIFF_SD = {"touch_gap_m": 2.0e-6,
                  2.38e-5: {"l_g_m": 0.0025, "l_c_over_l_g": 0.00011, "mu": 0.0026},
                  2.37e-4: {"l_g_m": 0.0027, "l_c_over_l_g": 0.00044, "mu": 0.0074}}


@pytest.mark.slow
def test_paced_shear_ladder_measures_what_the_virtual_one_does(tmp_path: Path) -> None:
    """Issue 24, item 6: the MCR 501 stream's times and the arm angle on one time base; the
    ladder at paced:100 gives l_g, l_c/l_g and mu per level as the virtual run does, within
    4 standard deviations of the clocks' difference over seeds (one overlap, two speeds)."""
    from gelrig.clock_check import record_ladder_levels

    runs = {clock: record_ladder_levels(tmp_path / clock.replace(":", "_"), clock, overlaps=1)
            for clock in ("virtual", "paced:100")}
    ref, got = runs["virtual"], runs["paced:100"]
    assert len(got) == len(ref) == 2
    assert abs(got[0]["touch_gap_m"] - ref[0]["touch_gap_m"]) <= 4 * LADDER_DIFF_SD["touch_gap_m"]
    for a, b in zip(got, ref, strict=True):
        assert (a["overlap_m"], a["speed_m_s"]) == (b["overlap_m"], b["speed_m_s"])
        sd = LADDER_DIFF_SD[b["speed_m_s"]]
        assert isinstance(sd, dict)
        for key in ("l_g_m", "l_c_over_l_g", "mu"):
            assert abs(a[key] / b[key] - 1) <= 4 * sd[key], (key, b["speed_m_s"], a[key], b[key])
