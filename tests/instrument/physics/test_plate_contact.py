"""Plate-on-sphere physics: the sign convention, laziness in blocks, and the hold."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import Material, hertz_prefactor, normal_force
from gelrig.instrument.physics.plate_contact import PlateSphereContact

MAT = Material.of(7146.0, [(630.0, 1413.0)])
R = 9.315e-3
TOUCH = 2e-3
SPEED = 0.002 * 18.63e-3
DEPTH = 0.06 * 18.63e-3


def ramp(t: float) -> float:
    """Plate 0.2 mm above the sphere at t = 0, moving in from t = 1 s, stopping at 6 %."""
    return min(TOUCH - 0.2e-3 + SPEED * max(t - 1.0, 0.0), TOUCH + DEPTH)


def ramp_v(t: np.ndarray) -> np.ndarray:
    return np.minimum(TOUCH - 0.2e-3 + SPEED * np.maximum(t - 1.0, 0.0), TOUCH + DEPTH)


def test_overlap_sign_convention() -> None:
    into = PlateSphereContact(MAT, R, TOUCH, lambda t: TOUCH + 1e-4)
    assert into.overlap([0.0])[0] == pytest.approx(1e-4)
    flipped = PlateSphereContact(MAT, R, TOUCH, lambda t: TOUCH - 1e-4, direction=-1)
    assert flipped.overlap([0.0])[0] == pytest.approx(1e-4)
    apart = PlateSphereContact(MAT, R, TOUCH, lambda t: TOUCH - 1e-4)
    assert apart.force(np.array([0.0, 1.0]))[-1] == 0.0


def test_elastic_force_is_hertz_with_the_papers_prefactor() -> None:
    elastic = Material(5000.0)
    c = PlateSphereContact(elastic, R, TOUCH, lambda t: TOUCH + 1e-3)
    expected = hertz_prefactor(R) * 5000.0 * 1e-3**1.5
    assert c.force(np.array([0.0, 1.0])) == pytest.approx([expected, expected])


def test_blocks_on_a_grid_equal_one_batch() -> None:
    dt = 0.01
    t = np.arange(0, 80.0, dt)
    reference = normal_force(t, ramp_v(t) - TOUCH, MAT, R)
    c = PlateSphereContact(MAT, R, TOUCH, ramp)
    parts, k = [], 0
    for n in (1, 7, 500, 3000, t.size - 3508):
        parts.append(c.force_on_grid(float(t[k]), dt, n))
        k += n
    assert np.concatenate(parts) == pytest.approx(reference, rel=1e-9, abs=1e-12)
    assert reference.max() > 0.05  # the plate did press into the sphere


def test_vectorised_and_scalar_trajectories_agree() -> None:
    a = PlateSphereContact(MAT, R, TOUCH, ramp)
    b = PlateSphereContact(MAT, R, TOUCH, ramp_v, vectorized=True)
    assert a.force_on_grid(0.0, 0.1, 900) == pytest.approx(b.force_on_grid(0.0, 0.1, 900))


def test_vectorised_trajectory_must_return_one_position_per_time() -> None:
    c = PlateSphereContact(MAT, R, TOUCH, lambda t: np.zeros(2), vectorized=True)
    with pytest.raises(ValueError, match="shape"):
        c.overlap(np.zeros(5))


def test_gap_between_queries_keeps_the_history() -> None:
    """A query long after the last one still sees the loading it did not sample."""
    t_end = 1.0 + (0.2e-3 + DEPTH) / SPEED + 100.0
    fine = np.linspace(0.0, t_end, 200_001)
    reference = normal_force(fine, ramp_v(fine) - TOUCH, MAT, R)[-1]
    gapped = PlateSphereContact(MAT, R, TOUCH, ramp, max_gap=0.5)
    gapped.force(np.array([0.0]))
    got = gapped.force(np.array([t_end]))[0]
    assert got == pytest.approx(reference, rel=1e-4)
    # Without filling, the loading history is one straight step and the relaxed part is wrong.
    coarse = PlateSphereContact(MAT, R, TOUCH, ramp, max_gap=1e9)
    coarse.force(np.array([0.0]))
    assert abs(coarse.force(np.array([t_end]))[0] - reference) > 10 * abs(got - reference)


def test_hold_relaxes_with_the_material_time() -> None:
    t_hold = 1.0 + (0.2e-3 + DEPTH) / SPEED
    c = PlateSphereContact(MAT, R, TOUCH, ramp)
    f = c.force_on_grid(0.0, 1.0, int(t_hold) + 3001)
    g = f / (hertz_prefactor(R) * DEPTH**1.5)
    i0 = math.ceil(t_hold)
    excess = g[i0:] - MAT.g_e
    # G - G_e decays as exp(-t/tau) during the hold.
    tau = -1.0 / np.polyfit(np.arange(excess.size), np.log(excess), 1)[0]
    assert tau == pytest.approx(1413.0, rel=1e-3)


def test_time_must_not_go_backwards() -> None:
    c = PlateSphereContact(MAT, R, TOUCH, ramp)
    c.force(np.array([5.0]))
    with pytest.raises(ValueError, match=r"backwards|decrease"):
        c.force(np.array([4.0]))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"sphere_radius": 0.0}, "sphere_radius"), ({"first_touch": math.nan}, "first_touch"),
     ({"direction": 2}, "direction"), ({"max_gap": 0.0}, "max_gap")],
)
def test_bad_parameters_name_the_field(kwargs: dict[str, float], field: str) -> None:
    args: dict[str, object] = {"material": MAT, "sphere_radius": R, "first_touch": TOUCH,
                               "plate_position": ramp}
    args.update(kwargs)
    with pytest.raises(ConfigError) as info:
        PlateSphereContact(**args)  # type: ignore[arg-type]
    assert info.value.field == field
