"""Simulated holds for the live fit: G(t) of a material with the paper's force noise, fed
block by block to a :class:`~gelrig.instrument.analysis.live_fit.LiveFit` as the ``ramp_hold`` step
does.

For the honesty study (tests, ``benchmarks/bench_live_fit.py``) and the README figure; no rig,
no clock: only the fit and the stopping rule are under test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gelrig.instrument.analysis.live_fit import LiveFit, LiveFitState, StopRule
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import Material, hertz_prefactor
from gelrig.instrument.physics.truth import FORCE_NOISE

# FORCE_NOISE: the rig file's force noise (N); with the paper's hold geometry G's noise (Pa)
# follows.
#: Seconds of samples a block carries (``ForceRecorder.dwell``'s hold blocks).
BLOCK = 4.0


def modulus_noise(force_noise: float = FORCE_NOISE, radius: float = paper.R_COMPRESSION,
                  depth: float = paper.DEPTH_HOLD) -> float:
    """Standard deviation of G(t) = F / (K delta^1.5) (Pa) for white force noise (N)."""
    return force_noise / (hertz_prefactor(radius, 0.5) * depth**1.5)


@dataclass(frozen=True)
class SimulatedHold:
    """One simulated hold: every refit, and where (s) and why it ended."""

    history: list[LiveFitState]
    ended: float
    reason: str  # "target" | "maximum" | "planned"


def simulate_hold(material: Material, terms: int, hold: float, rate: float, seed: int,
                  rule: StopRule | None = None, noise: float | None = None) -> SimulatedHold:
    """Feed ``hold`` s of ``material``'s G(t) plus white noise to a live fit in blocks; stop
    early when ``rule`` is met (checked after every refit, as the step does)."""
    rng = np.random.default_rng(seed)
    sigma = modulus_noise() if noise is None else noise
    fit = LiveFit(terms, hold, rate)
    per_block = max(1, round(BLOCK * rate))
    total = round(hold * rate)
    done = 0
    while done < total:
        n = min(per_block, total - done)
        t = (done + np.arange(n)) / rate
        fit.add(t, material.modulus(t) + rng.normal(0.0, sigma, n))
        done += n
        elapsed = done / rate
        if fit.due(elapsed) and fit.refit(elapsed) is not None and rule is not None \
                and rule.done(fit.history):
            return SimulatedHold(fit.history, elapsed, "target")
    return SimulatedHold(fit.history, done / rate, "maximum" if rule else "planned")
