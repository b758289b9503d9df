"""Least-squares fit of the contact model to every pass of a recorded ladder at once.

The paper fitted G_e, G_l, tau and mu by hand, separately to F_h and F_v. Here one parameter
set is fitted to both forces of all passes, driven by the measured motion (physics.md
section 2, docs/decisions/0030):

- the recorded arm angle and gap of every shear step, in time order, give the overlap
  ``delta = R1 + R2 - hypot(h, x)`` with ``x = wrap(angle - lower_angle) * L`` and
  ``h = R1 + R2 - (touch_gap - gap)``;
- one contact (:func:`gelrig.instrument.physics.contact_models.make_contact`) runs through that
whole trajectory;
  each pass is a fresh contact (the history ends where the overlap returns to <= 0), unless
  ``FitSetup.carry_history`` (a sensitivity option, docs/decisions/0140);
- ``F_h`` and ``F_v`` follow from :func:`gelrig.instrument.physics.sliding.resolve_forces` in the
frame of
  each pass's motion, and are compared with the baseline-corrected measured forces of
  :mod:`gelrig.instrument.analysis.shear_analysis`, each weighted by its noise.

Fitted: ``G_e``, ``G_i`` and ``tau_i`` (as logarithms, so they stay positive), ``mu``, and, by
default, the touch gap and the lower sphere's angle, which the contact search only estimates
(it supplies their start values). With ``FitSetup.anisotropic`` (the paper's fit: F_h with
G_l = 5 G_e, F_v with 4 G_e) the amplitudes are fitted separately for the two forces, reported
as ``G_i_h`` and ``G_i_v``; G_e, the tau_i and mu stay shared. The radii and the arm are
taken as given. Stretches where the spheres are far apart are reduced to their end points:
there ``x = 0`` and the recursion only resets (or, carried, decays) the history, which two
samples represent exactly.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import OptimizeResult, least_squares, nnls

from gelrig.instrument.analysis.fit_setup import FitSetup
from gelrig.instrument.analysis.shear_analysis import (
    BoolArray,
    PassResult,
    pass_forces,
    split_passes,
)
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import (
    FloatArray,
    Material,
    RelaxationTerm,
    effective_radius,
    hereditary_contacts,
    hertz_power,
    hertz_prefactor,
)
from gelrig.instrument.physics.contact_models import make_contact
from gelrig.instrument.physics.sliding import resolve_forces

IndexArray = NDArray[np.intp]

#: Samples further apart than this (overlap below -KEEP_GAP at the start values) are dropped
#: from the trajectory's interior of each apart stretch; it bounds how far the fitted geometry
#: may move from its start before the reduction would matter.
KEEP_GAP = 0.3e-3
#: Per unloading model: the relative finite-difference step of the Jacobian and the relative
#: cost change that ends the fit (None: scipy's defaults). MDR's force moves in small steps as
#: single elements enter and leave contact: a step near machine precision sees those and not
#: the slope, and at the noise floor the fit would otherwise oscillate by ~1e-6 of the cost,
#: far below what moves a parameter by a tenth of its standard error (~1e-4 of the cost).
DIFF_STEP: dict[str, float | None] = {"cutoff": None, "mdr": 1e-4}
FTOL: dict[str, float] = {"cutoff": 1e-8, "mdr": 1e-5}
#: z value of the two-sided 95 % confidence interval.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Trajectory:
    """The recorded motion and forces of all shear steps in time order (SI units)."""

    t: FloatArray
    angle: FloatArray
    gap: FloatArray
    torque: FloatArray
    normal_force: FloatArray
    pass_index: FloatArray
    direction: FloatArray

    @classmethod
    def from_steps(cls, steps: Sequence[Mapping[str, FloatArray]]) -> Trajectory:
        """Concatenate step columns (``t_s``, ``angle_rad``, ``gap_m``, ... ) by time."""
        if not steps:
            raise ConfigError("trajectory", "empty", "need at least one shear step's data")
        keys = {"t": "t_s", "angle": "angle_rad", "gap": "gap_m", "torque": "torque_Nm",
                "normal_force": "normal_force_N", "pass_index": "pass",
                "direction": "direction"}
        cols = {k: np.concatenate([np.asarray(s[c], dtype=float) for s in steps])
                for k, c in keys.items()}
        order = np.argsort(cols["t"], kind="stable")
        return cls(**{k: v[order] for k, v in cols.items()})

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass(frozen=True)
class Estimate:
    """One fitted parameter with its standard error and 95 % confidence interval."""

    name: str
    value: float
    stderr: float
    lo: float
    hi: float
    unit: str
    #: How the 95 % interval was found: "linearised" (value +- z se, on the log scale for
    #: moduli and time constants) or "profile" (profile likelihood, docs/decisions/0272).
    interval: str = "linearised"


@dataclass(frozen=True)
class ModelFit:
    """The fitted parameter set, its uncertainties and the quality of the fit."""

    material: Material
    mu: float
    touch_gap: float
    lower_angle: float
    estimates: tuple[Estimate, ...]
    rms_h: float
    rms_v: float
    noise_h: float
    noise_v: float
    n_passes: int
    n_points: int
    evaluations: int
    seconds: float
    extra: dict[str, object] = field(default_factory=dict)
    #: The material F_v was fitted with (anisotropic fits); None: ``material`` for both.
    material_vertical: Material | None = None

    def estimate(self, name: str) -> Estimate:
        for e in self.estimates:
            if e.name == name:
                return e
        raise KeyError(name)

    def rows(self) -> list[dict[str, object]]:
        """Table rows: parameter, value, stderr, 95 % interval, unit, how the interval was
        found."""
        return [{"parameter": e.name, "value": e.value, "stderr": e.stderr,
                 "ci95_lo": e.lo, "ci95_hi": e.hi, "unit": e.unit, "interval": e.interval}
                for e in self.estimates]


@dataclass
class _Problem:
    """Arrays the residual function needs, prepared once."""

    setup: FitSetup
    t: FloatArray
    angle: FloatArray
    gap: FloatArray
    points: FloatArray  # indices into the reduced trajectory
    direction: FloatArray  # at the points
    f_h: FloatArray
    f_v: FloatArray
    w_h: float
    w_v: float
    pass_of_point: FloatArray
    fixed_touch: float
    fixed_angle: float
    evaluations: int = 0

    def split(self, q: FloatArray) -> tuple[Material, float, float, float]:
        terms = self.setup.terms
        g_e = math.exp(q[0])
        relax = tuple(RelaxationTerm(math.exp(q[1 + 2 * i]), math.exp(q[2 + 2 * i]))
                      for i in range(terms))
        mu = float(q[1 + 2 * terms])
        if self.setup.fit_geometry:
            touch, angle = float(q[2 + 2 * terms]), float(q[3 + 2 * terms])
        else:
            touch, angle = self.fixed_touch, self.fixed_angle
        return Material(g_e, relax, self.setup.nu), mu, touch, angle

    def vertical(self, q: FloatArray, material: Material) -> Material | None:
        """The F_v material of an anisotropic fit (its amplitudes close ``q``), else None."""
        if not self.setup.anisotropic:
            return None
        terms = self.setup.terms
        first = q.size - terms
        return Material(material.g_e, tuple(
            RelaxationTerm(math.exp(q[first + i]), term.tau)
            for i, term in enumerate(material.relax)), material.nu)

    def geometry(self, touch: float, lower: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(x, h, delta) over the trajectory."""
        s = self.setup.s
        x = (np.remainder(self.angle - lower + math.pi, 2.0 * math.pi) - math.pi) * self.setup.arm
        h = s - (touch - self.gap)
        return x, h, s - np.hypot(h, x)

    def forces(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Model F_h (moving frame) and F_v at the fit points."""
        self.evaluations += 1
        material, mu, touch, lower = self.split(q)
        x, h, delta = self.geometry(touch, lower)
        i = self.points.astype(np.intp)
        psi = -self.direction * x[i] / h[i]
        f_perp = self._f_perp(material, delta)[i]
        f_h, f_v = resolve_forces(f_perp, psi, 1.0, mu)
        vertical = self.vertical(q, material)
        if vertical is not None:
            _, f_v = resolve_forces(self._f_perp(vertical, delta)[i], psi, 1.0, mu)
        return f_h, f_v

    def _f_perp(self, material: Material, delta: FloatArray) -> FloatArray:
        setup = self.setup
        contact = make_contact(material, effective_radius(setup.r1, setup.r2), setup.unloading,
                               carry_history=setup.carry_history)
        return contact.block(self.t, delta)

    def residual(self, q: FloatArray) -> FloatArray:
        f_h, f_v = self.forces(q)
        return np.concatenate(((f_h - self.f_h) * self.w_h, (f_v - self.f_v) * self.w_v))


def _reduce(t: FloatArray, keep: BoolArray) -> IndexArray:
    """Indices to keep: every sample flagged, plus both ends of each unflagged stretch."""
    flag = keep.copy()
    flag[0] = flag[-1] = True
    edges = np.flatnonzero(np.diff(keep.astype(np.int8)) != 0)
    flag[edges] = True
    flag[np.minimum(edges + 1, t.size - 1)] = True
    return np.flatnonzero(flag)


def _points(
    traj: Trajectory, results: Sequence[PassResult], setup: FitSetup
) -> tuple[list[IndexArray], FloatArray, FloatArray, FloatArray, FloatArray, float, float]:
    """Per pass: trajectory indices in a window around the contact, and measured forces."""
    idx_all: list[IndexArray] = []
    f_h_all: list[FloatArray] = []
    f_v_all: list[FloatArray] = []
    dirs: list[FloatArray] = []
    owner: list[FloatArray] = []
    noise_h, noise_v = [], []
    columns = {"t_s": traj.t, "angle_rad": traj.angle, "torque_Nm": traj.torque,
               "normal_force_N": traj.normal_force, "gap_m": traj.gap,
               "pass": traj.pass_index, "direction": traj.direction,
               "speed_m_s": np.zeros(len(traj)), "overlap_m": np.zeros(len(traj))}
    by_index = {r.index: r for r in results}
    for p in split_passes(columns):
        r = by_index.get(p.index)
        if r is None:
            continue
        p = type(p)(p.index, r.direction, r.speed, r.overlap, p.t, p.angle, p.torque,
                    p.normal_force, p.gap)
        f = pass_forces(p, setup.arm)
        # The window is sized by the local edges' l_c: the model fit does not move with the
        # whole-pass profile's few um (docs/decisions/0260, addendum).
        margin = 0.25 * r.local_l_c
        lo, hi = sorted((r.contact_start, r.contact_end))
        window = np.flatnonzero(f.moving & (f.theta > lo - margin) & (f.theta < hi + margin))
        stride = max(1, math.ceil(window.size / setup.max_points_per_pass))
        window = window[::stride]
        where = np.flatnonzero(traj.pass_index == p.index)[window]
        idx_all.append(where)
        f_h_all.append(f.f_h[window])
        f_v_all.append(f.f_v[window])
        dirs.append(np.full(window.size, r.direction))
        owner.append(np.full(window.size, float(p.index)))
        noise_h.append(f.noise_h)
        noise_v.append(f.noise_v)
    if not idx_all:
        raise ConfigError("model fit", "no passes", "nothing to fit")
    return (idx_all, np.concatenate(f_h_all), np.concatenate(f_v_all), np.concatenate(dirs),
            np.concatenate(owner), float(np.median(noise_h)), float(np.median(noise_v)))


def _start_moduli(
    problem: _Problem, mu: float, touch: float, lower: float
) -> list[float]:
    """(G_e, G_1, tau_1, ...) from non-negative linear least squares on F_v over a log grid of
    time constants (the model is linear in the moduli before the no-adhesion cutoff).

    The cached hereditary integrals are the cutoff model's. With ``unloading="mdr"`` only the
    samples where the contact grows enter: there MDR is the same linear model (Lee-Radok),
    while on the receding side its force depends on the moduli through the separation times
    and the cutoff model's start would be biased (the fit itself runs MDR throughout)."""
    setup = problem.setup
    x_arc, h, delta = problem.geometry(touch, lower)
    i = problem.points.astype(np.intp)
    xp = hertz_power(delta)
    k = hertz_prefactor(effective_radius(setup.r1, setup.r2), setup.nu)
    psi = -problem.direction * x_arc[i] / h[i]
    resolve = (1.0 - mu * psi) / np.hypot(1.0, psi)
    use = (xp[i] > 0) & (problem.f_v > 0)
    if setup.unloading != "cutoff":  # growing contact only: where the models are one
        growing = np.diff(delta, prepend=-np.inf) > 0
        use &= growing[i]
    if np.count_nonzero(use) < 10:
        raise ConfigError("model fit", int(np.count_nonzero(use)),
                          "too few samples in contact at the start geometry")
    dt = np.diff(problem.t, prepend=problem.t[0])
    taus = np.geomspace(10.0, 1e5, 13)
    cached = {float(tau): hereditary_contacts(dt, xp, float(tau), setup.carry_history)[i][use]
              for tau in taus}
    y = problem.f_v[use]
    base = (k * xp[i] * resolve)[use]
    best: tuple[float, list[float]] | None = None
    for combo in itertools.combinations(taus[::-1].tolist(), setup.terms):
        a = np.column_stack([base, *((k * resolve[use]) * cached[tau] for tau in combo)])
        coef, rnorm = nnls(a, y)
        if coef[0] <= 0:
            continue
        params = [float(coef[0])]
        for amp, tau in zip(coef[1:], combo, strict=True):
            params += [max(float(amp), 1e-3 * float(coef[0])), float(tau)]
        if best is None or rnorm < best[0]:
            best = (float(rnorm), params)
    if best is None:
        raise ConfigError("model fit", "start", "no positive modulus explains F_v")
    return best[1]


def _lag1(res: FloatArray, owner: FloatArray) -> float:
    """Lag-1 autocorrelation of the residuals within passes (0 for white noise)."""
    same = owner[1:] == owner[:-1]
    a, b = res[:-1][same], res[1:][same]
    if a.size < 3 or float(np.std(a)) == 0.0 or float(np.std(b)) == 0.0:
        return 0.0
    return float(np.clip(np.corrcoef(a, b)[0, 1], 0.0, 0.99))


#: Profile-likelihood intervals (docs/decisions/0272): an end is accepted when the signed root
#: of the profile deviance is within PROFILE_TOL of z_0.975; at most PROFILE_STEPS refits an
#: end; a refit whose cost is below the optimum's by more than BETTER (in deviance) restarts
#: the fit from it once.
PROFILE_TOL = 0.05
PROFILE_STEPS = 5
BETTER = 0.1


def _solve(problem: _Problem, q0: FloatArray, bounds: tuple[FloatArray, FloatArray],
           x_scale: FloatArray) -> OptimizeResult:
    setup = problem.setup
    # a wild trial step can square past the float range: the trust region rejects it (its
    # cost is inf) and shrinks, so the overflow is expected, not a fault
    with np.errstate(over="ignore"):
        return least_squares(problem.residual, q0, bounds=bounds, x_scale=x_scale,
                             method="trf", diff_step=DIFF_STEP[setup.unloading],
                             ftol=FTOL[setup.unloading])


class _Profile:
    """The fit's covariance at its optimum, and profile-likelihood intervals.

    Covariance: the larger, per parameter, of the white-noise one widened by the residuals'
    lag-1 correlation (ADR 0190) and the sandwich clustered by pass (errors correlated within
    a pass, F_h and F_v together; CR1). The profile deviance of parameter j is
    ``(RSS_j - RSS) / (s^2 c_j)`` with ``c_j`` that variance over the white-noise one, so a
    linear model's profile interval is the linearised one; where the ridge of G_e, G_i and
    tau_i curves, the profile follows it."""

    def __init__(self, problem: _Problem, result: OptimizeResult,
                 bounds: tuple[FloatArray, FloatArray], x_scale: FloatArray):
        self.problem, self.bounds, self.x_scale = problem, bounds, x_scale
        self.q = np.asarray(result.x, dtype=float).copy()
        res = np.asarray(result.fun, dtype=float)
        n, p = res.size, self.q.size
        self.rss = float(res @ res)
        self.s2 = self.rss / max(1, n - p)
        owner = problem.pass_of_point
        half = n // 2
        self.rho = max(_lag1(res[:half], owner), _lag1(res[half:], owner))
        self.inflation = (1.0 + self.rho) / (1.0 - self.rho)
        self.better: FloatArray | None = None
        self.refits = 0
        jac = np.asarray(result.jac, dtype=float)
        try:
            bread = np.linalg.inv(jac.T @ jac)
        except np.linalg.LinAlgError:
            self.cov = np.full((p, p), math.inf)
            self.err = np.full(p, math.inf)
            self.scale = np.ones(p)
            self.robust_ratio = np.full(p, math.nan)
            return
        white = bread * self.s2
        groups = np.concatenate((owner, owner))
        _, which = np.unique(groups, return_inverse=True)
        g = int(which.max()) + 1
        scores = np.zeros((g, p))
        np.add.at(scores, which, jac * res[:, None])
        meat = scores.T @ scores * (g / max(1, g - 1)) * ((n - 1) / max(1, n - p))
        robust = bread @ meat @ bread
        w = np.clip(np.diag(white), 1e-300, None)
        var = np.maximum(np.diag(white) * self.inflation, np.diag(robust))
        self.scale = var / w
        # the covariance the intervals' start values and the standard errors use
        d = np.sqrt(self.scale)
        self.cov = white * np.outer(d, d)
        self.err = np.sqrt(np.clip(var, 0.0, None))
        self.robust_ratio = np.sqrt(np.clip(np.diag(robust), 0.0, None) / w)

    def _refit(self, j: int, value: float, start: FloatArray) -> tuple[float, FloatArray]:
        """RSS and parameters of the fit with parameter ``j`` held at ``value``."""
        problem, q = self.problem, self.q
        free = np.arange(q.size) != j
        lo, hi = self.bounds[0][free], self.bounds[1][free]
        x0 = np.clip(start[free], lo, hi)
        full = q.copy()
        full[j] = value

        def residual(x: FloatArray) -> FloatArray:
            full[free] = x
            return problem.residual(full)

        setup = problem.setup
        with np.errstate(over="ignore"):  # a rejected wild trial step (see _solve)
            result = least_squares(residual, x0, bounds=(lo, hi),
                                   x_scale=self.x_scale[free], method="trf",
                                   diff_step=DIFF_STEP[setup.unloading],
                                   ftol=FTOL[setup.unloading])
        self.refits += 1
        out = q.copy()
        out[free] = result.x
        out[j] = value
        return float(result.fun @ result.fun), out

    def _root(self, j: int, rss: float, q_j: FloatArray) -> float:
        """The signed root of the profile deviance (records a lower optimum)."""
        dev = (rss - self.rss) / (self.s2 * self.scale[j])
        if dev < -BETTER and self.better is None:
            self.better = q_j
        return math.copysign(math.sqrt(max(dev, 0.0)), float(q_j[j] - self.q[j]))

    def end(self, j: int, sign: float) -> tuple[float, str]:
        """One end of parameter ``j``'s 95 % profile interval, and how it was found."""
        q, err = self.q, float(self.err[j])
        lo_b, hi_b = float(self.bounds[0][j]), float(self.bounds[1][j])
        slope = self.cov[:, j] / self.cov[j, j]  # the linearised ridge: start values
        points: list[tuple[float, float, FloatArray]] = [(0.0, 0.0, q)]
        d = sign * Z95 * err
        for _ in range(PROFILE_STEPS):
            value = min(max(float(q[j]) + d, lo_b), hi_b)
            d = value - float(q[j])
            near = min(points, key=lambda pt: abs(pt[0] - d))
            rss, qd = self._refit(j, value, near[2] + (d - near[0]) * slope)
            r = self._root(j, rss, qd)
            if self.better is not None:
                return value, "profile: a lower optimum found"
            if abs(abs(r) - Z95) <= PROFILE_TOL:  # close: the last secant step to z
                d0, r0, _ = min(points, key=lambda pt: abs(pt[0] - d))
                if abs(r) != abs(r0):
                    d = d0 + (Z95 - abs(r0)) * (d - d0) / (abs(r) - abs(r0))
                return min(max(float(q[j]) + d, lo_b), hi_b), "profile"
            points.append((d, r, qd))
            if abs(r) < Z95 and value in (lo_b, hi_b):
                return value, "profile (at the bound)"
            points.sort(key=lambda pt: abs(pt[0]))
            outer = next((k for k, pt in enumerate(points) if abs(pt[1]) > Z95), None)
            if outer is None:  # not yet beyond: extrapolate from the two outermost
                (d0, r0, _), (d1, r1, _) = points[-2], points[-1]
                growth = (abs(r1) - abs(r0)) / (abs(d1) - abs(d0)) if d1 != d0 else 0.0
                d = (sign * (abs(d1) + (Z95 - abs(r1)) / growth) if growth > 0
                     else 2.0 * d1)
                d = sign * min(abs(d), 4.0 * abs(d1))
            else:  # bracketed: interpolate
                (d0, r0, _), (d1, r1, _) = points[outer - 1], points[outer]
                d = d0 + (Z95 - abs(r0)) * (d1 - d0) / (abs(r1) - abs(r0))
        return float(q[j]) + d, f"profile (not within {PROFILE_TOL} after {PROFILE_STEPS} refits)"

    def intervals(self, indices: Sequence[int]) -> dict[int, tuple[tuple[float, float], str]]:
        """Profile intervals of ``indices`` (linearised where the covariance is not finite);
        stops early when a refit finds a lower optimum (``better``)."""
        out: dict[int, tuple[tuple[float, float], str]] = {}
        for j in indices:
            if not math.isfinite(float(self.err[j])) or self.err[j] <= 0:
                continue
            try:
                lo, how_lo = self.end(j, -1.0)
                if self.better is not None:
                    return out
                hi, how_hi = self.end(j, 1.0)
                if self.better is not None:
                    return out
            except (ValueError, OverflowError, np.linalg.LinAlgError) as exc:  # keep linear
                out[j] = ((float(self.q[j] - Z95 * self.err[j]),
                           float(self.q[j] + Z95 * self.err[j])),
                          f"linearised (profile failed: {exc})")
                continue
            out[j] = ((lo, hi), how_lo if how_lo == how_hi else f"{how_lo}; {how_hi}")
        return out


def fit_ladder(
    traj: Trajectory,
    results: Sequence[PassResult],
    setup: FitSetup,
    touch_gap: float,
    lower_angle: float,
    mu_start: float | None = None,
    profile_intervals: bool = True,
) -> ModelFit:
    """Fit the contact model to the analysed passes ``results`` of ``traj``.

    ``touch_gap`` (m) and ``lower_angle`` (rad) come from the contact search: start values
    when ``setup.fit_geometry``, fixed otherwise. ``mu_start`` defaults to the median of the
    per-pass estimates, else the paper's mu.

    Standard errors come from a sandwich clustered by pass (:class:`_Profile`); with
    ``profile_intervals`` (the default) the 95 % intervals of G_e, the G_i, tau_i and mu are
    profile-likelihood intervals (docs/decisions/0272), the others' linearised.
    """
    started = time.perf_counter()
    if not (math.isfinite(touch_gap) and math.isfinite(lower_angle)):
        raise ConfigError("model fit", (touch_gap, lower_angle),
                          "needs the touch gap and the lower sphere's angle (contact search)")
    idx_list, f_h, f_v, dirs, owner, noise_h, noise_v = _points(traj, results, setup)
    points_full = np.concatenate(idx_list)
    # Reduce the trajectory: keep samples that may be in contact, and the fit points.
    s = setup.s
    x0 = (np.remainder(traj.angle - lower_angle + math.pi, 2 * math.pi) - math.pi) * setup.arm
    delta0 = s - np.hypot(s - (touch_gap - traj.gap), x0)
    keep = delta0 > -KEEP_GAP
    keep[points_full] = True
    kept = _reduce(traj.t, keep)
    position = np.full(len(traj), -1, dtype=np.intp)
    position[kept] = np.arange(kept.size)
    problem = _Problem(
        setup, traj.t[kept], traj.angle[kept], traj.gap[kept],
        position[points_full].astype(float), dirs, f_h, f_v,
        1.0 / max(noise_h, 1e-15), 1.0 / max(noise_v, 1e-15), owner, touch_gap, lower_angle,
    )
    mus = [r.mu for r in results if math.isfinite(r.mu)]
    mu0 = mu_start if mu_start is not None else (float(np.median(mus)) if mus else paper.MU)
    mu0 = min(max(mu0, 0.0), 0.5)
    moduli = _start_moduli(problem, mu0, touch_gap, lower_angle)
    q0 = [math.log(v) for v in moduli] + [mu0]
    lower = [-np.inf] * len(moduli) + [0.0]
    upper = [np.inf] * len(moduli) + [1.0]
    scale = [0.1] * len(moduli) + [1e-3]
    if setup.fit_geometry:
        q0 += [touch_gap, lower_angle]
        lower += [touch_gap - 0.5 * KEEP_GAP, lower_angle - 0.5 * KEEP_GAP / setup.arm]
        upper += [touch_gap + 0.5 * KEEP_GAP, lower_angle + 0.5 * KEEP_GAP / setup.arm]
        scale += [1e-5, 1e-5 / setup.arm]
    if setup.anisotropic:  # the F_v amplitudes start where the F_h ones do
        q0 += [math.log(moduli[1 + 2 * k]) for k in range(setup.terms)]
        lower += [-np.inf] * setup.terms
        upper += [np.inf] * setup.terms
        scale += [0.1] * setup.terms
    bounds = (np.array(lower, dtype=float), np.array(upper, dtype=float))
    x_scale = np.array(scale)
    result = _solve(problem, np.array(q0), bounds, x_scale)
    profile = _Profile(problem, result, bounds, x_scale)
    intervals = profile.intervals(_profiled(setup)) if profile_intervals else {}
    restarted = profile.better is not None
    if profile.better is not None:  # a profile refit found a lower cost: restart there, once
        result = _solve(problem, profile.better, bounds, x_scale)
        refits = profile.refits
        profile = _Profile(problem, result, bounds, x_scale)
        profile.refits += refits
        intervals = profile.intervals(_profiled(setup)) if profile_intervals else {}
    q, err = profile.q, profile.err
    half = result.fun.size // 2
    material, mu, touch, angle = problem.split(q)
    estimates = _estimates(q, err, setup, intervals)
    f_h_model, f_v_model = problem.forces(q)
    return ModelFit(
        material=material, mu=mu, touch_gap=touch, lower_angle=angle,
        material_vertical=problem.vertical(q, material),
        estimates=tuple(estimates),
        rms_h=float(np.sqrt(np.mean((f_h_model - f_h) ** 2))),
        rms_v=float(np.sqrt(np.mean((f_v_model - f_v) ** 2))),
        noise_h=noise_h, noise_v=noise_v, n_passes=len(idx_list), n_points=int(half),
        evaluations=problem.evaluations, seconds=time.perf_counter() - started,
        extra={"unloading": setup.unloading, "anisotropic": setup.anisotropic,
               "lag1_correlation": profile.rho, "covariance_inflation": profile.inflation,
               "covariance": "max(white x lag-1 inflation, per-pass cluster sandwich)",
               "cluster_se_ratio": {name: float(v) for name, v in
                                    zip(_names(setup), profile.robust_ratio, strict=False)},
               "restarted_from_profile": restarted,
               "intervals": {_names(setup)[i]: how for i, (_, how) in intervals.items()}
               if intervals else "linearised (profile likelihood not asked for)",
               "profile_refits": profile.refits,
               "trajectory_samples": int(kept.size), "status": result.message},
    )


def describe_setup(setup: FitSetup) -> str:
    """The fitted model in words: its unloading model and whether F_h and F_v share G_i."""
    how = ("G_i fitted separately for F_h (_h) and F_v (_v)" if setup.anisotropic
           else "one G_i for F_h and F_v")
    carried = ", history carried across separations" if setup.carry_history else ""
    return f"{setup.unloading} unloading, {how}{carried}"


def _exp(x: float) -> float:
    """exp, inf beyond the float range (an interval a fit does not bound)."""
    return math.exp(x) if x < 709.0 else math.inf


def _names(setup: FitSetup) -> list[str]:
    """The estimate's name of each entry of the parameter vector."""
    names = ["G_e"]
    for k in range(setup.terms):
        names += [f"G_{k + 1}_h" if setup.anisotropic else f"G_{k + 1}", f"tau_{k + 1}"]
    names.append("mu")
    if setup.fit_geometry:
        names += ["touch_gap", "lower_angle"]
    if setup.anisotropic:
        names += [f"G_{k + 1}_v" for k in range(setup.terms)]
    return names


def _profiled(setup: FitSetup) -> list[int]:
    """Indices of the parameters whose intervals are profiled: the material's and mu."""
    return [i for i, name in enumerate(_names(setup))
            if name not in ("touch_gap", "lower_angle")]


def _estimates(q: FloatArray, err: FloatArray, setup: FitSetup,
               ends: Mapping[int, tuple[tuple[float, float], str]] | None = None
               ) -> list[Estimate]:
    """The estimates in report order; ``ends`` (index: ((lo, hi) in the fitted parameter,
    i.e. log for moduli, how)) replace the linearised intervals where given."""
    out = []
    ends = ends or {}
    names = _names(setup)

    def interval(i: int) -> tuple[float, float, str]:
        if i in ends:
            (lo, hi), how = ends[i]
            return lo, hi, "profile" if how.startswith("profile") else how
        return float(q[i] - Z95 * err[i]), float(q[i] + Z95 * err[i]), "linearised"

    def log_param(i: int, unit: str) -> None:
        v = math.exp(q[i])
        lo, hi, how = interval(i)
        out.append(Estimate(names[i], v, v * float(err[i]), _exp(lo), _exp(hi), unit, how))

    def lin_param(i: int, unit: str) -> None:
        lo, hi, how = interval(i)
        out.append(Estimate(names[i], float(q[i]), float(err[i]), lo, hi, unit, how))

    log_param(0, "Pa")
    for k in range(setup.terms):
        log_param(1 + 2 * k, "Pa")
        if setup.anisotropic:
            log_param(q.size - setup.terms + k, "Pa")
        log_param(2 + 2 * k, "s")
    m = 1 + 2 * setup.terms
    lin_param(m, "1")
    if setup.fit_geometry:
        lin_param(m + 1, "m")
        lin_param(m + 2, "rad")
    return out


def model_forces(
    traj: Trajectory, fit: ModelFit, setup: FitSetup
) -> tuple[FloatArray, FloatArray]:
    """Model F_h (frame of each pass's motion; 0-direction samples use the clockwise frame)
    and F_v at every sample of ``traj``, from the fitted parameters."""
    s = setup.s
    x = (np.remainder(traj.angle - fit.lower_angle + math.pi, 2 * math.pi) - math.pi) * setup.arm
    h = s - (fit.touch_gap - traj.gap)
    delta = s - np.hypot(h, x)
    radius = effective_radius(setup.r1, setup.r2)

    def f_perp_of(material: Material) -> FloatArray:
        return make_contact(material, radius, setup.unloading,
                            carry_history=setup.carry_history).block(traj.t, delta)

    f_perp = f_perp_of(fit.material)
    f_perp_v = f_perp if fit.material_vertical is None else f_perp_of(fit.material_vertical)
    frame = np.where(traj.direction == 0, 1.0, traj.direction)
    mu = np.where(traj.direction == 0, 0.0, fit.mu)
    psi = -frame * x / h
    d = np.hypot(1.0, psi)
    return f_perp * (psi + mu) / d, f_perp_v * (1.0 - mu * psi) / d
