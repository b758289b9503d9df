"""A recorded speed-ladder step analysed whole: passes, levels, and the ladder-wide model fit.

Arrays in, dataclasses out (:mod:`gelrig.instrument.analysis.shear_analysis` per pass,
:mod:`gelrig.instrument.analysis.model_fit` for the fit); the report
(:mod:`gelrig.instrument.reports.ladder`) and
``gelrig analyze`` format them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from gelrig.instrument.analysis.model_fit import (
    FitSetup,
    ModelFit,
    Trajectory,
    fit_ladder,
    model_forces,
)
from gelrig.instrument.analysis.shear_analysis import (
    K_SIGMA,
    S_PAPER,
    LadderAnalysis,
    PassForces,
    RecordedPass,
    analyse_ladder,
    geometric_l_g,
    pass_forces,
)
from gelrig.instrument.physics.contact import FloatArray


@dataclass(frozen=True)
class LadderStep:
    """A ladder step's analysed passes with their recorded samples and forces.

    ``passes`` and ``analysis.results`` are in the same order; ``forces`` maps a pass index to
    its baseline-corrected forces.
    """

    analysis: LadderAnalysis
    passes: list[RecordedPass]
    forces: dict[int, PassForces]

    def levels(self, fit: ModelFit | None = None, s: float = math.nan) -> list[dict[str, float]]:
        """One row per (overlap, speed) (:meth:`LadderAnalysis.levels`) with ``l_g_geom_m``:
        l_g from the geometry with the fitted touch gap (NaN without a fit); ``s = R1 + R2``."""
        rows = self.analysis.levels()
        for row in rows:
            row["l_g_geom_m"] = math.nan if fit is None else geometric_l_g(
                s, fit.touch_gap, self.passes, self.analysis.results,
                row["overlap_m"], row["speed_m_s"])
        return rows


@dataclass(frozen=True)
class LadderModel:
    """The model fitted to a ladder, and its F_h, F_v at every sample of the fitted motion."""

    fit: ModelFit
    trajectory: Trajectory
    f_h: FloatArray
    f_v: FloatArray


def analyse_ladder_step(
    columns: Mapping[str, FloatArray], arm: float, travel: float | None = None,
    k_sigma: float = K_SIGMA, s: float = S_PAPER,
) -> LadderStep:
    """Every complete pass of a ladder step's ``columns``; ``arm`` (m), planned ``travel`` (m),
    ``s`` = R1 + R2 (m).

    Raises ConfigError when the columns are not those of a ladder step.
    """
    analysis, passes = analyse_ladder(columns, arm, travel, k_sigma, s)
    return LadderStep(analysis, passes, {p.index: pass_forces(p, arm) for p in passes})


def fit_ladder_model(
    step: LadderStep, history: Sequence[Mapping[str, FloatArray]], setup: FitSetup,
    touch_gap: float, lower_angle: float,
) -> LadderModel:
    """Fit the contact model to all analysed passes of ``step`` at once.

    ``history`` holds the columns of every shear step up to and including this one (the motion
    the contact has seen; only this step's passes labelled), ``touch_gap`` (m) and
    ``lower_angle`` (rad) the start geometry. Raises ConfigError, ValueError or LinAlgError
    when the fit cannot be made.
    """
    trajectory = Trajectory.from_steps(history)
    fit = fit_ladder(trajectory, step.analysis.results, setup, touch_gap, lower_angle)
    f_h, f_v = model_forces(trajectory, fit, setup)
    return LadderModel(fit, trajectory, f_h, f_v)
