import math
import threading
import time

import pytest

from gelrig.instrument.core.clock import Clock, PacedClock, RealClock, VirtualClock, clock_from_spec
from gelrig.instrument.core.errors import ConfigError


def test_virtual_sleep_advances_instantly():
    clock = VirtualClock()
    start = time.monotonic()
    clock.sleep(3000.0)
    assert clock.now() == 3000.0
    clock.sleep_until(3500.0)
    assert clock.now() == 3500.0
    assert time.monotonic() - start < 0.5


def test_virtual_is_monotonic():
    clock = VirtualClock(10.0)
    clock.sleep(-5.0)
    clock.sleep_until(1.0)
    assert clock.now() == 10.0
    with pytest.raises(ValueError):
        clock.advance(-1.0)


def test_virtual_threads_add_up():
    clock = VirtualClock()

    def worker() -> None:
        for _ in range(1000):
            clock.sleep(0.001)

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert clock.now() == pytest.approx(4.0)


def test_paced_runs_faster_than_real():
    clock = PacedClock(rate=200.0)
    t0, r0 = clock.now(), time.monotonic()
    clock.sleep(2.0)  # 10 ms of real time
    elapsed_real = time.monotonic() - r0
    assert clock.now() - t0 >= 2.0
    assert 0.005 < elapsed_real < 0.5


def test_paced_rate_change_has_no_jump_and_inf_is_instant():
    clock = PacedClock(rate=1.0)
    before = clock.now()
    clock.set_rate(math.inf)
    after = clock.now()
    assert 0 <= after - before < 0.1
    r0 = time.monotonic()
    clock.sleep(1e6)
    assert clock.now() >= after + 1e6
    assert time.monotonic() - r0 < 0.1
    with pytest.raises(ValueError):
        clock.set_rate(0)


def test_real_clock_and_protocol():
    clock = RealClock()
    a = clock.now()
    clock.sleep(0.01)
    assert clock.now() - a >= 0.009
    for c in (RealClock(), VirtualClock(), PacedClock()):
        assert isinstance(c, Clock)


@pytest.mark.parametrize("spec,kind", [("real", RealClock), ("virtual", VirtualClock),
                                       ("paced:10", PacedClock), ("paced:inf", PacedClock)])
def test_clock_from_spec(spec, kind):
    assert isinstance(clock_from_spec(spec), kind)


@pytest.mark.parametrize("spec", ["fast", "paced:", "paced:-1", "paced:x"])
def test_clock_from_spec_rejects(spec):
    with pytest.raises(ConfigError, match="paced:K"):
        clock_from_spec(spec)


def test_paced_waits_only_scales_the_waits_not_the_work():
    clock = PacedClock(rate=100.0, waits_only=True)
    t0 = clock.now()
    time.sleep(0.02)  # 20 ms of host work: 20 ms of lab time, not 2 s
    worked = clock.now() - t0
    assert 0.015 <= worked < 0.5
    r0 = time.monotonic()
    t1 = clock.now()
    clock.sleep(1.0)  # a wait: 10 ms of real time
    assert time.monotonic() - r0 < 0.5
    assert clock.now() >= t1 + 1.0


def test_paced_waits_only_never_passes_the_earliest_deadline():
    clock = PacedClock(rate=1000.0, waits_only=True)
    seen: list[float] = []
    deadline = clock.now() + 0.5

    def waiter() -> None:
        clock.sleep_until(deadline)
        seen.append(clock.now())

    th = threading.Thread(target=waiter)
    th.start()
    # while it waits, nobody sees the time beyond its deadline
    for _ in range(50):
        assert clock.now() <= deadline + 1e-9 or not th.is_alive()
        time.sleep(0.0002)
    th.join()
    # waking late in real time does not carry the time past the deadline by the pace
    assert seen[0] == pytest.approx(deadline, abs=0.05)


def test_clock_from_spec_paced_waits_only_unless_served():
    run = clock_from_spec("paced:10")
    served = clock_from_spec("paced:10", waits_only=False)
    assert isinstance(run, PacedClock) and run.waits_only
    assert isinstance(served, PacedClock) and not served.waits_only
