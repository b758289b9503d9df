"""Recorded passes reproduce the paper's features (physics.md section 5, features 1-5).

Everything is computed from torque and normal force recorded through the driver (pyvisa-py
over TCP, simulator in a thread sharing the VirtualClock), at delta_max = 0.78 mm and the
paper's parameters, at the four sliding speeds in both directions.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from numpy.typing import NDArray

from gelrig.drivers.mcr501 import MCR501, open_resource_manager
from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.contracts.rheometer import StreamPoint
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics.sliding import SlidingGeometry, speed_from_rpm
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer

SPEEDS = (2.38e-5, 4.75e-5, 1.19e-4, 2.37e-4)
DELTA_MAX = 0.78e-3
MARGIN = 1.0e-3
#: Virtual seconds between stream reads: 600 points at 10 Hz, well inside the 4096-point buffer.
READ_PERIOD = 60.0
REST = 12_000.0  # s between passes: six relaxation times, so passes do not disturb each other
CFG = SimConfig(start_referenced=False, lower_angle=1.3, seed=11)
GEO = SlidingGeometry(CFG.r1, CFG.r2, DELTA_MAX)
FArr = NDArray[np.float64]


@dataclass(frozen=True)
class Pass:
    """One recorded pass in the frame of its motion."""

    speed: float
    sign: int
    psi: FArr  # offset of the moving centre behind the fixed one, along the motion (m)
    f_h: FArr  # horizontal force resisting the motion (N), bearing offset removed
    f_v: FArr  # normal force (N), baseline removed
    noise_v: float  # standard deviation of F_v before contact (N)


def _smooth(y: FArr, n: int = 9) -> FArr:
    return np.convolve(y, np.ones(n) / n, mode="same")


def goto(drv: MCR501, clock: VirtualClock, angle: float) -> None:
    """Turn the arm to ``angle`` (rad) with a proportional approach, then stop."""
    arm = drv.config.arm
    for _ in range(10_000):
        err = angle - drv.angle()
        if abs(err) * arm < 1e-6:
            break
        drv.rotate(math.copysign(min(4e-3, abs(err) * arm / 0.5 + 1e-7), err))
        clock.sleep(0.05)
    drv.stop()
    clock.sleep(1.0)


def record_pass(drv: MCR501, clock: VirtualClock, speed: float, sign: int) -> Pass:
    arm = drv.config.arm
    lower = CFG.lower_angle
    drv.set_gap(CFG.touch_gap + 1e-3)
    goto(drv, clock, lower - sign * (GEO.psi0 + MARGIN) / arm)
    drv.set_gap(CFG.touch_gap - DELTA_MAX)
    drv.start_stream(0.1)  # 10 Hz
    drv.rotate(sign * speed)
    end = clock.now() + 2 * (GEO.psi0 + MARGIN) / speed
    points: list[StreamPoint] = []
    while clock.now() < end:  # read before the instrument's stream buffer fills
        keep_moving(clock, drv, min(READ_PERIOD, end - clock.now()), drv.config.motion_bound)
        points += drv.read_stream()
    drv.stop()
    points += drv.read_stream()
    assert not drv.status().overflow
    drv.stop_stream()
    theta = np.array([p.theta for p in points])
    torque = np.array([p.torque for p in points])
    f_v = np.array([p.normal_force for p in points])
    psi = -sign * (theta - lower * arm)
    free = psi > GEO.psi0 + 0.2e-3  # before first touch, turning freely at speed
    free[: max(3, int(0.02e-3 / (speed * 0.1)))] = False  # skip the start ramp
    offset = float(np.mean(torque[free]))
    base_v = float(np.mean(f_v[free]))
    return Pass(
        speed, sign, psi, sign * (torque - offset) / arm, f_v - base_v, float(np.std(f_v[free]))
    )


@pytest.fixture(scope="module")
def passes() -> Iterator[dict[tuple[float, int], Pass]]:
    rm = open_resource_manager("@py")
    clock = VirtualClock()
    sim = MCR501Simulator(clock, CFG)
    out: dict[tuple[float, int], Pass] = {}
    with SimulatorServer(sim) as server:
        drv = MCR501(server.resource, clock, resource_manager=rm).open()
        try:
            drv.zero_gap()
            for speed in SPEEDS:
                for sign in (1, -1):
                    out[(speed, sign)] = record_pass(drv, clock, speed, sign)
                    clock.sleep(REST)
        finally:
            drv.close()
            rm.close()
    yield out


def peak_trough(p: Pass) -> tuple[float, float]:
    f = _smooth(p.f_h)
    return float(f.max()), float(-f.min())


def contact_length(p: Pass) -> float:
    """Span of travel over which F_v stands clear of the noise (first rise to return)."""
    on = np.flatnonzero(p.f_v > max(1e-4, 5 * p.noise_v))
    return float(p.psi[on[0]] - p.psi[on[-1]])


@pytest.mark.parametrize("sign", [1, -1])
def test_feature_1_peak_larger_than_trough(
    passes: dict[tuple[float, int], Pass], sign: int
) -> None:
    for speed in SPEEDS:
        peak, trough = peak_trough(passes[(speed, sign)])
        assert peak > 1.05 * trough > 0, (speed, peak, trough)


@pytest.mark.parametrize("sign", [1, -1])
def test_feature_2_trough_grows_with_speed(
    passes: dict[tuple[float, int], Pass], sign: int
) -> None:
    peaks, troughs = zip(*(peak_trough(passes[(v, sign)]) for v in SPEEDS), strict=True)
    assert all(b > a for a, b in itertools.pairwise(troughs)), troughs
    # the peak grows less than the trough
    assert troughs[-1] - troughs[0] > 2 * (peaks[-1] - peaks[0]) > 0, (peaks, troughs)


@pytest.mark.parametrize("sign", [1, -1])
def test_feature_3_contact_length(passes: dict[tuple[float, int], Pass], sign: int) -> None:
    ratios = [contact_length(passes[(v, sign)]) / GEO.l_g for v in SPEEDS]
    assert all(r < 1 for r in ratios), ratios
    assert all(b > a for a, b in itertools.pairwise(ratios)), ratios
    assert ratios[0] < 0.96 and ratios[-1] > 0.97  # towards 1 at higher speed


@pytest.mark.parametrize("sign", [1, -1])
def test_feature_4_friction_offset_on_top(passes: dict[tuple[float, int], Pass], sign: int) -> None:
    mu = CFG.mu
    for speed in SPEEDS:
        p = passes[(speed, sign)]
        f_h, f_v = _smooth(p.f_h), _smooth(p.f_v)
        order = np.argsort(p.psi)
        on_top_h = float(np.interp(0.0, p.psi[order], f_h[order]))
        on_top_v = float(np.interp(0.0, p.psi[order], f_v[order]))
        assert on_top_h / on_top_v == pytest.approx(mu, rel=0.1)
        # the zero crossing of F_h lies towards detachment, at psi = -mu h
        inside = np.abs(p.psi) < GEO.psi0 / 2
        idx = np.flatnonzero(inside[:-1] & (f_h[:-1] > 0) & (f_h[1:] <= 0))
        assert idx.size == 1
        i = int(idx[0])
        psi_zero = p.psi[i] + (p.psi[i + 1] - p.psi[i]) * f_h[i] / (f_h[i] - f_h[i + 1])
        assert psi_zero < 0
        assert psi_zero == pytest.approx(-mu * GEO.h, abs=10e-6)


@pytest.mark.parametrize("sign", [1, -1])
def test_feature_5_normal_force_weakly_speed_dependent(
    passes: dict[tuple[float, int], Pass], sign: int
) -> None:
    peaks = [float(_smooth(passes[(v, sign)].f_v).max()) for v in SPEEDS]
    assert all(b > a for a, b in itertools.pairwise(peaks)), peaks
    assert (peaks[-1] - peaks[0]) / peaks[0] < 0.1


def test_lab_frame_torque_sign_mirrors(passes: dict[tuple[float, int], Pass]) -> None:
    # Pass.f_h already undoes the lab sign: a clockwise pass records positive torque while
    # approaching, a counter-clockwise pass negative; both resist the motion.
    for speed in SPEEDS:
        cw, ccw = passes[(speed, 1)], passes[(speed, -1)]
        assert peak_trough(cw) == pytest.approx(peak_trough(ccw), rel=0.01)


def _search(drv: MCR501, clock: VirtualClock, sign: int, threshold: float = 0.2e-3) -> float | None:
    """Rotate at 0.5 rpm across the lower sphere; the angle where |torque| passes threshold."""
    speed = speed_from_rpm(0.5, drv.config.arm)
    start = drv.angle()
    drv.rotate(sign * speed)
    try:
        while abs(drv.angle() - start) < 2 * (GEO.psi0 + 3e-3) / drv.config.arm:
            clock.sleep(0.05)
            if abs(drv.torque()) > threshold:
                return drv.angle()
        return None
    finally:
        drv.stop()


@pytest.mark.parametrize("sign", [1, -1])
def test_torque_threshold_detects_contact_at_half_rpm(sign: int) -> None:
    clock = VirtualClock()
    cfg = SimConfig(start_referenced=True, lower_angle=2.0, start_angle=2.0 - sign * 0.4)
    sim = MCR501Simulator(clock, cfg)
    rm = open_resource_manager("@py")
    with (
        SimulatorServer(sim) as server,
        MCR501(server.resource, clock, resource_manager=rm) as drv,
    ):
        arm = drv.config.arm
        drv.set_gap(cfg.touch_gap + 0.2e-3)  # apart: a full sweep finds nothing
        assert _search(drv, clock, sign) is None
        clock.sleep(2.0)
        drv.set_gap(cfg.touch_gap - DELTA_MAX)
        goto(drv, clock, cfg.lower_angle - sign * 0.4)
        found = _search(drv, clock, sign)
        assert found is not None
        psi = -sign * (found - cfg.lower_angle) * arm
        assert 0 < psi < GEO.psi0  # in contact, still approaching
    rm.close()
