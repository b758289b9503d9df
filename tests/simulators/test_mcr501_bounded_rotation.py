"""Renewing a time-limited rotation changes nothing the simulated MCR 501 records (ADR 0201).

Literal request lines straight into the simulator: a pass through contact turned by one long
``:ROT[CW;rpm;3600]`` and the same pass renewed every 0.5 s as gelrig does
(``:ROT[CW;rpm;1.5]``) give the same stream records to the last digit; a pass left without
renewals stops 1.5 s after the last one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics.sliding import rpm_from_speed
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig

SPEED = 2e-4  # m/s at the 27 mm arm
RPM = rpm_from_speed(SPEED, 0.027)


def _pass(duration: float, renew_every: float | None, seconds: float = 60.0
          ) -> tuple[MCR501Simulator, list[str], float]:
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True, seed=3, lower_angle=0.8,
                                           start_angle=0.5))
    assert sim.handle(":GAP[2.5000]") == [":GAP[OK]"]  # 0.5 mm below the 3 mm touch gap
    clock.sleep(10.0)
    assert sim.handle(":RUN[0.1]") == [":RUN[OK]"]
    start = float(sim.handle(":ANG[?]")[0][5:-1])
    rotate = f":ROT[CW;{RPM:.6e};{duration:g}]"
    assert sim.handle(rotate) == [":ROT[OK]"]
    records: list[str] = []
    step = renew_every or 0.5
    for k in range(1, round(seconds / step) + 1):
        clock.sleep(step)
        if renew_every is not None:
            assert sim.handle(rotate) == [":ROT[OK]"]
        if k % 4 == 0:  # a read every 2 s, as the ladder's recorder does
            records += sim.handle("#DATA[?]")[1:]
    return sim, records, start


def _column(records: list[str], i: int) -> np.ndarray:
    return np.array([float(r[6:-1].split(";")[i]) for r in records])


def test_renewals_leave_every_record_unchanged() -> None:
    whole_sim, whole, _ = _pass(3600.0, None)
    renewed_sim, renewed, _ = _pass(1.5, 0.5)
    assert renewed_sim.renewals == 120 and whole_sim.renewals == 0
    assert len(whole) == 600
    assert np.abs(_column(whole, 3)).max() > 0.01  # through contact: newtons of F_v
    assert renewed == whole


def test_a_pass_left_alone_stops_after_its_segment() -> None:
    sim, records, start = _pass(1.5, None, seconds=10.0)
    t, angle = _column(records, 0), _column(records, 1)
    omega = SPEED / 0.027
    ramp = omega / sim.config.acceleration
    moving = np.flatnonzero(np.diff(angle) > 0)
    assert t[moving[-1] + 1] <= 1.5 + ramp + 0.1  # the last sample still moving (10 Hz)
    assert np.all(angle[moving[-1] + 1:] == angle[-1])  # at rest ever since
    # ramp up, 1.5 s, ramp down: as far as 1.5 s at full speed
    assert angle[-1] - start == pytest.approx(math.degrees(omega * 1.5), abs=2e-7)
