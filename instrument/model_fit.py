"""Least-squares fit of the contact model to every pass of a recorded ladder at once.

The paper fitted G_e, G_l, tau and mu by hand, separately to F_h and F_v. Here one parameter
set is fitted to both forces of all passes, driven by the measured motion (physics.md
section 2, docs/decisions/0030):

- the recorded arm angle and gap of every shear step, in time order, give the overlap
  ``delta = R1 + R2 - hypot(h, x)`` with ``x = wrap(angle - lower_angle) * L`` and
  ``h = R1 + R2 - (touch_gap - gap)``;
- one contact (:func:`instrument.contact_models.make_contact`) runs through that whole trajectory;
  each pass is a fresh contact (the history ends where the overlap returns to <= 0), unless
  ``FitSetup.carry_history`` (a sensitivity option, docs/decisions/0140);
- ``F_h`` and ``F_v`` follow from :func:`instrument.sliding.resolve_forces` in the frame of
  each pass's motion, and are compared with the baseline-corrected measured forces of
  :mod:`instrument.shear_analysis`, each weighted by its noise.

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
from scipy.optimize import least_squares, nnls

from instrument.contact import (
    FloatArray,
    Material,
    RelaxationTerm,
    effective_radius,
    hereditary_contacts,
    hertz_power,
    hertz_prefactor,
)
from instrument.contact_models import UNLOADING_MODELS, make_contact
from instrument.errors import ConfigError
from instrument.shear_analysis import BoolArray, PassResult, pass_forces, split_passes
from instrument.sliding import resolve_forces

IndexArray = NDArray[np.intp]

#: Samples of a pass that enter the fit at most (a uniform stride over its contact window).
MAX_POINTS_PER_PASS = 300
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
class FitSetup:
    """What the fit takes as given: radii (m), arm (m), Poisson ratio, number of terms, and
    the model's options: separate F_h and F_v amplitudes (``anisotropic``), the unloading
    model, and whether the history is carried across separations (off: fresh contacts)."""

    r1: float
    r2: float
    arm: float
    nu: float = 0.5
    terms: int = 1
    fit_geometry: bool = True
    max_points_per_pass: int = MAX_POINTS_PER_PASS
    anisotropic: bool = False
    unloading: str = "cutoff"
    carry_history: bool = False

    def __post_init__(self) -> None:
        if self.terms not in (1, 2):
            raise ConfigError("terms", self.terms, "allowed: 1 or 2")
        if self.unloading not in UNLOADING_MODELS:
            raise ConfigError("unloading", self.unloading,
                              f"allowed: {', '.join(UNLOADING_MODELS)}")

    @property
    def s(self) -> float:
        return self.r1 + self.r2


@dataclass(frozen=True)
class Estimate:
    """One fitted parameter with its standard error and 95 % confidence interval."""

    name: str
    value: float
    stderr: float
    lo: float
    hi: float
    unit: str


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
        """Table rows: parameter, value, stderr, 95 % interval, unit."""
        return [{"parameter": e.name, "value": e.value, "stderr": e.stderr,
                 "ci95_lo": e.lo, "ci95_hi": e.hi, "unit": e.unit} for e in self.estimates]


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
        margin = 0.25 * r.l_c
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


def fit_ladder(
    traj: Trajectory,
    results: Sequence[PassResult],
    setup: FitSetup,
    touch_gap: float,
    lower_angle: float,
    mu_start: float | None = None,
) -> ModelFit:
    """Fit the contact model to the analysed passes ``results`` of ``traj``.

    ``touch_gap`` (m) and ``lower_angle`` (rad) come from the contact search: start values
    when ``setup.fit_geometry``, fixed otherwise. ``mu_start`` defaults to the median of the
    per-pass estimates, else 5e-3.
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
    mu0 = mu_start if mu_start is not None else (float(np.median(mus)) if mus else 5e-3)
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
    result = least_squares(problem.residual, np.array(q0), bounds=(lower, upper),
                           x_scale=np.array(scale), method="trf",
                           diff_step=DIFF_STEP[setup.unloading], ftol=FTOL[setup.unloading])
    q = result.x
    n = result.fun.size
    half = n // 2
    dof = max(1, n - q.size)
    rss = float(np.sum(result.fun**2))
    rho = max(_lag1(result.fun[:half], owner), _lag1(result.fun[half:], owner))
    inflation = (1.0 + rho) / (1.0 - rho)
    try:
        cov = np.linalg.inv(result.jac.T @ result.jac) * rss / dof * inflation
        err = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        err = np.full(q.size, math.inf)
    material, mu, touch, angle = problem.split(q)
    estimates = _estimates(q, err, setup)
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
               "lag1_correlation": rho, "covariance_inflation": inflation,
               "trajectory_samples": int(kept.size), "status": result.message},
    )


def describe_setup(setup: FitSetup) -> str:
    """The fitted model in words: its unloading model and whether F_h and F_v share G_i."""
    how = ("G_i fitted separately for F_h (_h) and F_v (_v)" if setup.anisotropic
           else "one G_i for F_h and F_v")
    carried = ", history carried across separations" if setup.carry_history else ""
    return f"{setup.unloading} unloading, {how}{carried}"


def _estimates(q: FloatArray, err: FloatArray, setup: FitSetup) -> list[Estimate]:
    out = []

    def log_param(name: str, i: int, unit: str) -> None:
        v = math.exp(q[i])
        out.append(Estimate(name, v, v * float(err[i]), math.exp(q[i] - Z95 * err[i]),
                            math.exp(q[i] + Z95 * err[i]), unit))

    def lin_param(name: str, i: int, unit: str) -> None:
        v = float(q[i])
        out.append(Estimate(name, v, float(err[i]), v - Z95 * float(err[i]),
                            v + Z95 * float(err[i]), unit))

    log_param("G_e", 0, "Pa")
    suffix = "_h" if setup.anisotropic else ""
    for k in range(setup.terms):
        log_param(f"G_{k + 1}{suffix}", 1 + 2 * k, "Pa")
        if setup.anisotropic:
            log_param(f"G_{k + 1}_v", q.size - setup.terms + k, "Pa")
        log_param(f"tau_{k + 1}", 2 + 2 * k, "s")
    m = 1 + 2 * setup.terms
    lin_param("mu", m, "1")
    if setup.fit_geometry:
        lin_param("touch_gap", m + 1, "m")
        lin_param("lower_angle", m + 2, "rad")
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
