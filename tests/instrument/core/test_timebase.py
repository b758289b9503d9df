import numpy as np
import pytest

from gelrig.instrument.core.timebase import SampleClock


def arrivals(drift_ppm: float, seconds: float, rate: float = 100.0, block: int = 10,
             transfer: int = 32, latency: float = 1e-3, jitter: float = 2e-3, t0: float = 5.0,
             seed: int = 0):
    """(last index, host time) of each read of ``block`` samples from a device whose clock
    runs ``drift_ppm`` fast, delivering ``transfer`` samples per USB transfer."""
    rng = np.random.default_rng(seed)
    true_rate = rate * (1 + drift_ppm * 1e-6)
    out = []
    for end in range(block, int(seconds * rate), block):
        last = end - 1
        transfer_end = (last // transfer + 1) * transfer - 1
        arrived = t0 + transfer_end / true_rate + latency + jitter * rng.random()
        late = 0.3 if rng.random() < 0.05 else 0.0  # a read that did not wait
        out.append((transfer_end, arrived + 2e-4 + late))
    return out


@pytest.mark.parametrize("drift", [-100.0, 0.0, 100.0])
def test_drift_is_estimated_from_the_earliest_arrivals(drift: float) -> None:
    clock = SampleClock(100.0, 4.9995, 5.0005)
    for last, t in arrivals(drift, 120.0):
        clock.arrived(last, t)
    assert clock.drift_ppm == pytest.approx(drift, abs=10.0)
    # sample 12000 (two minutes in) on the run's clock within a millisecond
    true = 5.0 + 12000 / (100.0 * (1 + drift * 1e-6))
    assert float(clock.times(np.array([12000.0]))[0]) == pytest.approx(true, abs=1e-3)


def test_times_never_go_back_when_the_estimate_changes() -> None:
    clock = SampleClock(100.0, 5.0, 5.0)
    stamped = []
    k = 0
    for last, t in arrivals(100.0, 60.0):
        clock.arrived(last, t)
        n = last + 1 - k
        stamped.append(clock.times(np.arange(k, k + n, dtype=float)))
        k += n
    t = np.concatenate(stamped)
    assert np.all(np.diff(t) > 0)
    mapping = clock.mapping("force").as_dict()
    assert mapping["uncertainty_s"] == 0.0 and mapping["details"]["drift_estimated"]


def test_periodic_arrivals_narrow_to_the_send_times() -> None:
    """Messages sent every 0.1 s, read every 0.32 s (a DAQ transfer's wait): each arrival
    window is up to 0.32 s wide; shifted by the period they intersect to a few ms, and
    always hold the true send time."""
    from gelrig.instrument.core.timebase import PeriodicArrivals

    period, t0 = 0.1, 0.0371
    reads = np.arange(0.0, 30.0, 0.32) + 0.004 * np.sin(np.arange(94))
    lock = PeriodicArrivals(period)
    widths = []
    last_read = 0.0
    k = 1
    for r in reads[1:]:
        while t0 + k * period <= r:
            lo, hi = lock.add(last_read, r)
            assert lo <= t0 + k * period <= hi
            widths.append(hi - lo)
            k += 1
        last_read = r
    assert lock.resets == 0
    assert np.median(widths[40:]) < 0.03  # against 0.32 s unnarrowed


def test_periodic_arrivals_start_again_when_the_period_is_not_the_one_assumed() -> None:
    from gelrig.instrument.core.timebase import PeriodicArrivals

    lock = PeriodicArrivals(0.1)
    for k in range(1, 20):  # sent every 0.13 s, each window 5 ms wide
        lo, hi = lock.add(0.13 * k, 0.13 * k + 0.005)
        assert lo <= 0.13 * k <= hi
    assert lock.resets >= 9


def test_periodic_arrivals_count_a_message_skipped() -> None:
    """A message with no window is still counted: the next keeps its place in the stream."""
    from gelrig.instrument.core.timebase import PeriodicArrivals

    lock = PeriodicArrivals(0.1)
    for k in range(1, 6):
        lock.add(0.1 * k - 0.03, 0.1 * k + 0.03)
    lock.skip()  # message 6
    lo, hi = lock.add(0.7 - 0.03, 0.7 + 0.001)
    assert lo <= 0.7 <= hi and lock.resets == 0
