"""The simulator's physics and instrument realism: contact model, history, motion, sensors."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gelrig.drivers.mcr501 import MCR501
from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.sliding import SlidingGeometry, shear_pass
from gelrig.simulators.mcr501 import DirectLink, MCR501Simulator, ShearCell, SimConfig
from gelrig.simulators.mcr501.motion import Lift, Spin

DELTA = 0.78e-3


Trace = tuple[ShearCell, list[float], list[float], list[float]]


def _pass_cell(
    cfg: SimConfig, speed: float, sign: int, cell: ShearCell | None = None, t0: float = 0.0
) -> Trace:
    """Drive a ShearCell through one pass (no wire, no noise); return psi, F_v, torque."""
    geo = SlidingGeometry(cfg.r1, cfg.r2, DELTA)
    if cell is None:
        start = cfg.lower_angle - sign * (geo.psi0 + 0.5e-3) / cfg.arm
        cell = ShearCell(replace(cfg, start_angle=start, start_gap=cfg.touch_gap - DELTA), t0)
    t = cell.t_int
    interval = 0.05e-3 / speed
    cell.start_stream(t, interval)
    cell.set_speed(t, sign * speed / cfg.arm)
    t_end = t + 2 * (geo.psi0 + 0.5e-3) / speed
    cell.set_speed(t_end, 0.0)
    cell.advance(t_end + 1.0)
    psi = [-sign * ((s.angle - cfg.lower_angle) * cfg.arm) for s in cell.samples]
    f_v = [s.normal_force for s in cell.samples]
    torque = [s.torque for s in cell.samples]
    cell.stop_stream(cell.t_int)
    return cell, psi, f_v, torque


@pytest.mark.parametrize(("speed", "sign"), [(2.38e-5, 1), (2.37e-4, -1)])
def test_pass_matches_the_contact_model(speed: float, sign: int) -> None:
    cfg = SimConfig(torque_offset=0.0, acceleration=50.0)
    _, psi, f_v, torque = _pass_cell(cfg, speed, sign)
    geo = SlidingGeometry(cfg.r1, cfg.r2, DELTA)
    model = shear_pass(geo, cfg.material, speed, mu=cfg.mu, margin=0.5e-3,
                       dt=0.01e-3 / speed)  # fmt: skip
    order = np.argsort(model.psi)
    want_v = np.interp(psi, model.psi[order], model.f_v[order])
    want_m = sign * cfg.arm * np.interp(psi, model.psi[order], model.f_h[order])
    peak = float(np.max(want_v))
    assert np.max(np.abs(np.array(f_v) - want_v)) < 2e-3 * peak
    assert np.max(np.abs(np.array(torque) - want_m)) < 2e-3 * peak * cfg.arm
    assert np.max(np.abs(torque)) > 2e-4  # the pass really went through contact


def _second_over_first(cfg: SimConfig, rest: float) -> float:
    speed = 1.19e-4
    cell, _, f_v1, _ = _pass_cell(cfg, speed, 1)
    cell.advance(cell.t_int + rest)
    _, _, f_v2, _ = _pass_cell(cfg, speed, -1, cell)
    assert max(f_v1) > 0.09
    return max(f_v2) / max(f_v1)


def test_each_pass_is_a_fresh_contact() -> None:
    cfg = SimConfig(acceleration=50.0)
    for rest in (0.0, 2000.0):
        assert _second_over_first(cfg, rest) == pytest.approx(1.0, abs=1e-9)


def test_with_carry_history_a_new_pass_meets_the_decayed_history_of_the_last() -> None:
    cfg = SimConfig(acceleration=50.0, carry_history=True)
    fresh = _second_over_first(cfg, 0.0)
    later = _second_over_first(cfg, 2000.0)
    rested = _second_over_first(cfg, 20_000.0)
    assert fresh < later < rested  # the history left by the first pass decays
    assert fresh < 0.98
    assert rested == pytest.approx(1.0, abs=1e-3)


def test_anisotropic_vertical_force_uses_its_own_modulus() -> None:
    vertical = Material.of(4e3, [(1.6e4, 2000.0)])
    iso = SimConfig(acceleration=50.0, torque_offset=0.0)
    aniso = SimConfig(acceleration=50.0, torque_offset=0.0, material_vertical=vertical)
    _, psi, f_v_iso, m_iso = _pass_cell(iso, 1.19e-4, 1)
    _, psi2, f_v_aniso, m_aniso = _pass_cell(aniso, 1.19e-4, 1)
    assert np.array_equal(psi, psi2)
    assert m_aniso == m_iso  # F_h (the torque) keeps the horizontal material
    geo = SlidingGeometry(iso.r1, iso.r2, DELTA)
    model = shear_pass(geo, vertical, 1.19e-4, mu=iso.mu, margin=0.5e-3, dt=0.01e-3 / 1.19e-4)
    order = np.argsort(model.psi)
    want_v = np.interp(psi, model.psi[order], model.f_v[order])
    assert np.max(np.abs(np.array(f_v_aniso) - want_v)) < 2e-3 * float(np.max(want_v))
    assert max(f_v_aniso) < 0.99 * max(f_v_iso)


def test_hold_relaxes_with_the_material_time_scale() -> None:
    clock = VirtualClock()
    cfg = SimConfig(start_referenced=True, start_angle=0.8, lower_angle=0.8, lift_speed=1e-3,
                    start_gap=3.2e-3)  # fmt: skip
    sim = MCR501Simulator(clock, cfg)
    drv = MCR501(DirectLink(sim), clock).open()
    drv.set_gap(cfg.touch_gap - 0.5e-3)
    drv.hold()
    f0 = drv.normal_force()
    clock.sleep(2000.0)
    f1 = drv.normal_force()
    g = cfg.material
    ratio = (g.g_e + g.relax[0].g * math.exp(-1.0)) / g.g_instant
    assert f1 / f0 == pytest.approx(ratio, rel=0.01)
    assert drv.torque() == pytest.approx(0.0, abs=5e-7)  # on top, at rest: no horizontal force


def test_overlap_wraps_with_the_revolution() -> None:
    cfg = SimConfig(start_gap=3e-3 - DELTA)
    cell = ShearCell(cfg, 0.0)
    phi = np.array([cfg.lower_angle, cfg.lower_angle + 2 * math.pi, cfg.lower_angle + math.pi])
    x, h = cell.geometry(phi, np.full(3, cfg.start_gap))
    assert x[0] == pytest.approx(0.0) and x[1] == pytest.approx(0.0, abs=1e-12)
    assert abs(x[2]) == pytest.approx(math.pi * cfg.arm)
    assert h[0] == pytest.approx(cfg.r1 + cfg.r2 - DELTA)


def test_spin_ramps_at_constant_acceleration() -> None:
    spin = Spin(1.0, 0.2, 0.0, 0.4, 0.5)
    assert spin.ramp_end == pytest.approx(1.8)
    phi, omega = spin.at(np.array([1.0, 1.4, 1.8, 3.8]))
    assert phi == pytest.approx([0.2, 0.2 + 0.25 * 0.16, 0.2 + 0.25 * 0.64, 0.36 + 0.8])
    assert omega == pytest.approx([0.0, 0.2, 0.4, 0.4])
    back = spin.command(3.8, -0.4)
    assert back.ramp_end == pytest.approx(3.8 + 1.6)
    assert back.state(5.4)[1] == pytest.approx(-0.4)
    assert back.state(4.6) == pytest.approx((1.16 + 0.4 * 0.8 - 0.25 * 0.64, 0.0))
    assert spin.halt(2.0).state(9.0) == (spin.state(2.0)[0], 0.0)


def test_lift_travels_at_constant_speed() -> None:
    lift = Lift(0.0, 10e-3, 8e-3, 1e-3)
    assert lift.end == pytest.approx(2.0)
    assert lift.at(np.array([0.0, 1.0, 2.0, 5.0])) == pytest.approx([10e-3, 9e-3, 8e-3, 8e-3])
    assert lift.moving(1.9) and not lift.moving(2.0)
    assert lift.halt(0.5).gap(7.0) == pytest.approx(9.5e-3)


def _free_stream(seed: int, offset: float = 2e-6) -> tuple[np.ndarray, np.ndarray]:
    clock = VirtualClock()
    cfg = SimConfig(seed=seed, torque_offset=offset, torque_noise=1e-7, torque_resolution=1e-9)
    sim = MCR501Simulator(clock, cfg)
    drv = MCR501(DirectLink(sim), clock).open()
    drv.rotate(-1e-3)
    clock.sleep(1.0)
    drv.start_stream(0.01)
    keep_moving(clock, drv, 20.0, drv.config.motion_bound)  # renewed as gelrig's waits do
    pts = drv.read_stream()
    drv.stop()
    return np.array([p.torque for p in pts]), np.array([p.normal_force for p in pts])


def test_free_rotation_shows_offset_noise_and_resolution() -> None:
    torque, force = _free_stream(3)
    assert torque.size == 2000
    assert np.mean(torque) == pytest.approx(-2e-6, abs=1e-8)  # drag opposes the motion
    assert np.std(torque) == pytest.approx(1e-7, rel=0.1)
    assert np.std(force) == pytest.approx(SimConfig().normal_force_noise, rel=0.1)
    steps = torque / 1e-9
    assert np.allclose(steps, np.round(steps), atol=1e-3)
    assert np.all(np.abs(torque) < 0.2e-3 / 10)  # far below the contact-search threshold


def test_noise_is_seeded() -> None:
    a, _ = _free_stream(5)
    b, _ = _free_stream(5)
    c, _ = _free_stream(6)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
