"""The hold finder and the creep fit on synthetic records of the one-term model (exact, so the
fits must return the material they were made with)."""

from __future__ import annotations

import numpy as np
import pytest

from gelrig.instrument.analysis.creep import Uncertain, fit_creep
from gelrig.instrument.analysis.segments import find_holds
from gelrig.instrument.physics.contact import hereditary, hertz_prefactor

G_E, G_1, TAU = 7000.0, 2500.0, 40.0
TAU_C = TAU * (G_E + G_1) / G_E
R = 9e-3
K = hertz_prefactor(R)
STEP = 1e-3 / 34554.96  # the Z825B's encoder step (m)
T = np.arange(0.0, 250.0, 0.01)


def relaxation_record(noise: float = 0.0, seed: int = 1) -> dict[str, np.ndarray]:
    """Ramp to 0.8 mm in 40 s from 20 um before touch, hold: force from the model."""
    delta = np.clip(-20e-6 + T * (0.82e-3 / 40.0), -20e-6, 0.8e-3)
    x = np.maximum(delta, 0) ** 1.5
    dt = np.diff(T, prepend=T[0])
    force = K * (G_E * x + G_1 * hereditary(dt, x, TAU))
    force += np.random.default_rng(seed).normal(0, noise, T.size)
    return {"t_s": T, "position_m": 5e-3 + delta, "delta_m": delta, "force_N": force}


def creep_record(noise: float = 0.0, seed: int = 1) -> dict[str, np.ndarray]:
    """Force ramped to 50 mN in 30 s, then held: the overlap from the creep compliance
    (x = (J_e F - dJ H) / K), the plate on the encoder's steps."""
    force = 0.05 * np.clip((T - 10.0) / 30.0, 0.0, 1.0)
    dt = np.diff(T, prepend=T[0])
    j_e, d_j = 1 / G_E, 1 / G_E - 1 / (G_E + G_1)
    x = (j_e * force - d_j * hereditary(dt, force, TAU_C)) / K
    delta = np.cbrt(np.maximum(x, 0.0)) ** 2
    delta[T < 10.0] = -20e-6 + T[T < 10.0] * 2e-6
    z = np.round((5e-3 + delta) / STEP) * STEP
    force = force + np.random.default_rng(seed).normal(0, noise, T.size)
    return {"t_s": T, "position_m": z, "delta_m": z - 5e-3, "force_N": force}


def test_a_still_plate_in_contact_is_a_relaxation_hold() -> None:
    cols = relaxation_record(2e-4)
    (hold,) = find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols["delta_m"],
                         STEP)
    assert hold.kind == "relaxation"
    assert 40.0 <= hold.t0 <= 42.0 and hold.duration == pytest.approx(208.0, abs=2.0)


def test_a_held_force_with_the_plate_moving_is_a_creep_hold() -> None:
    cols = creep_record(2e-4)
    (hold,) = find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols["delta_m"],
                         STEP)
    assert hold.kind == "creep"  # the ramp's last second is within the force band already
    assert 38.0 <= hold.t0 <= 42.0 and hold.level == pytest.approx(0.05, rel=1e-3)


def test_no_hold_out_of_contact_or_shorter_than_the_minimum() -> None:
    cols = relaxation_record(2e-4)
    assert find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols["delta_m"], STEP,
                      min_duration=300.0) == []
    clear = {**cols, "delta_m": cols["delta_m"] - 2e-3, "force_N": cols["force_N"] * 0.0}
    assert find_holds(clear["t_s"], clear["position_m"], clear["force_N"], clear["delta_m"],
                      STEP) == []


@pytest.mark.parametrize("noise", [0.0, 2e-4])
def test_the_creep_fit_returns_the_material(noise: float) -> None:
    cols = creep_record(noise)
    (hold,) = find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols["delta_m"],
                         STEP)
    fit = fit_creep(cols["t_s"][:hold.end], cols["delta_m"][:hold.end],
                    cols["force_N"][:hold.end], hold.start, R, loading=0)
    assert fit.is_resolved and not fit.partial, (fit.not_resolved, fit.partial)
    for name, truth in (("G_e", G_E), ("G_1", G_1), ("tau_1", TAU), ("tau_c", TAU_C)):
        value, err = fit.values[name], fit.stderr[name]
        assert abs(value - truth) < max(3 * err, 2e-3 * truth), (name, value, err, truth)


def test_without_the_loading_g_1_is_not_a_result() -> None:
    cols = creep_record(2e-4)
    (hold,) = find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols["delta_m"],
                         STEP)
    fit = fit_creep(cols["t_s"][:hold.end], cols["delta_m"][:hold.end],
                    cols["force_N"][:hold.end], hold.start, R, loading=None)
    assert fit.is_resolved
    assert abs(fit.values["tau_c"] - TAU_C) < max(3 * fit.stderr["tau_c"], 2e-3 * TAU_C)
    assert abs(fit.values["G_e"] - G_E) < max(3 * fit.stderr["G_e"], 2e-3 * G_E)
    if fit.partial:  # G_1 and tau_1 then show no values
        assert np.isnan(fit.value("G_1")) and np.isnan(fit.value("tau_1"))


def test_the_creep_fit_carries_the_touchs_and_the_baselines_errors() -> None:
    """ADR 0375: first touch and the force's baseline are inputs the fit takes as exact; their
    standard errors are carried by refits. A baseline error moves G_e by its share of the
    held force (G ~ F / delta^1.5), a touch error by 1.5 of its share of the overlap."""
    cols = creep_record(2e-4)
    (hold,) = find_holds(cols["t_s"], cols["position_m"], cols["force_N"], cols["delta_m"],
                         STEP)
    args = (cols["t_s"][:hold.end], cols["delta_m"][:hold.end], cols["force_N"][:hold.end],
            hold.start, R)
    bare = fit_creep(*args, loading=0)
    sigma_b, sigma_z = 20e-6, 0.4e-6
    with_base = fit_creep(*args, loading=0, inputs=Uncertain(0.0, sigma_b))
    with_touch = fit_creep(*args, loading=0, inputs=Uncertain(sigma_z, 0.0))
    force = 0.05
    overlap = float(np.mean(cols["delta_m"][hold.start:hold.end]))
    for fit, share in ((with_base, sigma_b / force), (with_touch, 1.5 * sigma_z / overlap)):
        added = np.sqrt(fit.stderr["G_e"] ** 2 - bare.stderr["G_e"] ** 2) / G_E
        assert added == pytest.approx(share, rel=0.1)
    # a later touch raises G_e and a larger baseline lowers it: errors correlated positively
    # partly cancel, negatively add; uncorrelated lie between
    both = {rho: fit_creep(*args, loading=0, inputs=Uncertain(sigma_z, sigma_b, rho))
            for rho in (-1.0, 0.0, 1.0)}
    assert both[1.0].stderr["G_e"] < both[0.0].stderr["G_e"] < both[-1.0].stderr["G_e"]


def test_the_creep_fit_takes_the_adcs_mean_error_off_a_held_force(monkeypatch) -> None:
    """Below one code of noise (0.1 mN on 0.3 mN codes) the codes' mean is not the force, and
    a creep holds the force at one place between two codes for its whole hold: G_e read 3
    standard errors low on average over 12 seeds; with the quantiser's expected error taken
    off (``creep._dequantised``), within about one."""
    import gelrig.instrument.analysis.creep as creep

    q = 0.3e-3

    def mean_z(dequantise: bool) -> float:
        if not dequantise:
            monkeypatch.setattr(creep, "_dequantised", lambda t, f: f)
        z = []
        for seed in range(12):
            cols = creep_record(1e-4, seed)
            force = np.round((cols["force_N"] - 0.31 * q) / q) * q + 0.31 * q
            (hold,) = find_holds(cols["t_s"], cols["position_m"], force, cols["delta_m"], STEP)
            fit = fit_creep(cols["t_s"][:hold.end], cols["delta_m"][:hold.end],
                            force[:hold.end], hold.start, R, loading=0)
            z.append((fit.values["G_e"] - G_E) / fit.stderr["G_e"])
        monkeypatch.undo()
        return float(np.mean(z))

    assert mean_z(True) > -1.5
    assert mean_z(False) < -2.5  # the test can tell
