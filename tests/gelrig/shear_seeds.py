"""The paper's shear ladder over many noise seeds, cheaply and faithfully.

A full paper ladder through the simulated rig costs 7-20 s of CPU per seed. The sensor noise
is the only thing a seed changes in the ladder's samples: the twin integrates the same
contact for every seed and adds the noise when a stream record is read
(``MCR501Simulator._read_stream``: torque noise, then normal-force noise, each rounded to the
sensor's resolution). So the ladder is recorded once through the whole rig without noise and
at the wire's precision (:func:`quiet_run`), and each seed's record is that one with the
twin's noise model applied to its torque and normal-force columns (:func:`noisy_columns`;
:func:`noisy_run` writes it to a run directory, for ``gelrig analyze``). What this leaves
out: the contact search's own scatter (its touch gap sets the true overlap, which the
reference figures take from the recorded gap, as for a full run). The slow test in
``test_shear_per_pass_seeds.py`` runs the whole rig per seed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any
from unittest import mock

import h5py
import numpy as np

from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.store import RunDirectory
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.truth import ShearSample
from gelrig.protocols.rigfile import ShearRigSpec
from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.mcr501.instrument import MCR501Simulator
from tests.gelrig import paper_ladder


def _quiet_simulator(clock: Clock, truth: ShearSample, rheometer: RheometerConfig
                     ) -> MCR501Simulator:
    """The twin without sensor noise, its resolution finer than the wire's digits (torque
    1e-9 N m, force 1e-6 N): what it streams is the truth at the wire's precision."""
    return MCR501Simulator(clock, SimConfig.of(truth, rheometer, torque_noise=0.0,
                                               normal_force_noise=0.0, torque_resolution=1e-12,
                                               normal_force_resolution=1e-9))


def quiet_run(path: Path, proto: Any = None, **simulator: Any) -> RunDirectory:
    """The paper ladder (or ``proto``) recorded through the whole rig without sensor noise
    (the rig file's ``[simulator]`` entries overridden by ``simulator``)."""
    with mock.patch("gelrig.simulators.twins.shear.shear_simulator", _quiet_simulator):
        return paper_ladder.record(path, paper_ladder.rig(**simulator),
                                   proto or paper_ladder.protocol())


def sensor(spec: ShearRigSpec | None = None) -> SimConfig:
    """The simulated rheometer of ``spec`` (default the built-in rig): its noise figures."""
    spec = spec or paper_ladder.rig()
    return SimConfig.of(spec.simulator, spec.rheometer.config)


def noisy_columns(columns: dict[str, FloatArray], seed: int,
                  spec: ShearRigSpec | None = None) -> dict[str, FloatArray]:
    """``columns`` of a noise-free ladder with the twin's sensor noise of ``spec`` (default
    the built-in rig) drawn from ``seed``: per sample a torque normal then a force normal,
    each value rounded to its resolution, as the simulated MCR 501 reports a stream."""
    cfg = sensor(spec)
    n = columns["torque_Nm"].size
    z = np.random.default_rng(seed).standard_normal(2 * n)
    t_res, f_res = cfg.torque_resolution, cfg.normal_force_resolution
    out = dict(columns)
    out["torque_Nm"] = np.rint((columns["torque_Nm"] + cfg.torque_noise * z[0::2]) / t_res
                               ) * t_res
    out["normal_force_N"] = np.rint((columns["normal_force_N"]
                                     + cfg.normal_force_noise * z[1::2]) / f_res) * f_res
    return out


def noisy_run(quiet: RunDirectory, path: Path, seed: int, step: int = 1) -> RunDirectory:
    """A copy of ``quiet`` whose ladder step ``step`` carries the noise of ``seed``."""
    run = quiet.copy_to(path)
    noisy = noisy_columns(run.read_step(step), seed)
    record = next(s for s in run.read_metadata()["steps"] if s["index"] == step)
    with h5py.File(run.step_file(record), "r+") as handle:
        for name in ("torque_Nm", "normal_force_N"):
            handle[name][...] = noisy[name]
    return run


#: The README's per-pass bounds (issue 26): l_g to the chord at the true overlap (relative),
#: |l_c(C) - l_c(AC)| (m), l_c/l_g to the fresh-contact model, mu to the truth (relative).
BOUNDS = {"l_g": 0.003, "l_c_C_AC": 10e-6, "l_c_over_l_g": 0.0035, "mu": 0.05}


class Truth:
    """What each pass of a ladder should show, from the rig's hidden truth and the recorded
    gap: the chord at the true overlap and the fresh-contact model's l_c/l_g (cached)."""

    def __init__(self, spec: ShearRigSpec | None = None):
        self.spec = spec or paper_ladder.rig()
        self._ratio: dict[tuple[float, float], float] = {}

    def level(self, gap: float, speed: float) -> tuple[float, float, float]:
        """(true overlap, chord, model l_c/l_g) of a pass at recorded ``gap`` and ``speed``."""
        from gelrig.instrument.physics.sliding import SlidingGeometry

        truth = self.spec.simulator
        overlap = truth.touch_gap - gap
        key = (round(overlap, 10), speed)
        geo = SlidingGeometry(truth.r1, truth.r2, overlap)
        if key not in self._ratio:
            self._ratio[key] = paper_ladder.model_ratio(geo, truth.material, speed, truth.mu,
                                                        truth.unloading)
        return overlap, geo.l_g, self._ratio[key]


def pass_errors(results: list[Any], passes: list[Any], truth: Truth) -> list[dict[str, float]]:
    """Per pass: its errors against the truth, in the units of :data:`BOUNDS`."""
    gaps = {p.index: float(np.median(p.gap)) for p in passes}
    by_level: dict[tuple[float, float], dict[float, Any]] = {}
    for r in results:
        by_level.setdefault((round(r.overlap, 9), r.speed), {})[r.direction] = r
    mu = truth.spec.simulator.mu
    rows = []
    for r in results:
        pair = by_level[(round(r.overlap, 9), r.speed)]
        _, chord, ratio = truth.level(gaps[r.index], r.speed)
        rows.append({
            "pass": r.index, "overlap_m": r.overlap, "speed_m_s": r.speed,
            "direction": r.direction,
            "l_g": r.l_g / chord - 1.0,
            "l_c_C_AC": abs(pair[1.0].l_c - pair[-1.0].l_c) if len(pair) == 2 else np.nan,
            "l_c_C_AC_se": math.hypot(pair[1.0].l_c_stderr, pair[-1.0].l_c_stderr)
            if len(pair) == 2 else np.nan,
            "l_c_over_l_g": r.ratio - ratio,
            "mu": r.mu / mu - 1.0,
        })
    return rows


def failures(rows: list[dict[str, float]]) -> list[str]:
    """One line per pass and bound that is not met (NaN fails)."""
    out = []
    for row in rows:
        for key, bound in BOUNDS.items():
            if not abs(row[key]) <= bound:
                out.append(f"pass {row['pass']} ({row['overlap_m'] * 1e3:.2f} mm, "
                           f"{row['speed_m_s']:.3g} m/s, {'C' if row['direction'] > 0 else 'AC'}"
                           f"): {key} {row[key]:+.4g} beyond {bound:g}")
    return out
