"""Per-pass quantities of a recorded sliding-speed ladder (paper, section "Results").

Definitions (docs/decisions/0030):

- Forces: ``F_h = s (M - M_0) / L`` in the frame of the motion (``s`` = +1 clockwise, -1
  anticlockwise; docs/decisions/0022) and ``F_v = N - N_0``; the baselines ``M_0`` and ``N_0``
  are medians over the first :data:`BASELINE_FRACTION` of the moving part of the pass, well
  before contact, so the bearing drag and any normal-force offset drop out.
- Contact: a sample is in contact when ``|F_h|`` or ``F_v`` exceeds :data:`K_SIGMA` times its
  noise (:func:`gelrig.instrument.core.noise.robust_sigma` of the baseline window); the first
  and last threshold crossings (``contact_start``, ``contact_end``) only seed the edge fits
  and are their fallback.
- Edges (docs/decisions/0260): first touch (``touch``) is the onset model -- Hertz at the
  instantaneous modulus along the sliding geometry, F_h ~ delta^1.5 psi/d and F_v ~
  delta^1.5 h/d, zero before the touch -- fitted to F_h and F_v over a window of travel
  (:data:`ONSET_BEFORE`, :data:`ONSET_AFTER`), detachment (``detach``) a polynomial in the
  travel left that falls to zero there (:data:`DETACH_BEFORE`, :data:`DETACH_AFTER`); each
  with a free offset per force, a Huber loss on residuals in units of the noise, and a
  standard error. The windows are travel, not sample counts, so a fast pass is fitted over
  the same arc as a slow one. ``l_c`` runs from touch to detachment.
- Whole-pass profile (docs/decisions/0260, addendum; :func:`refine_edges`): the local edges
  start a fit of each pass's whole in-contact F_h and F_v to the fresh-contact shape
  (:func:`profile_basis`: delta^1.5 along the sliding geometry and its integrals over the
  travel, any Prony series at constant speed, cut off where F_perp reaches zero), both edges
  free, at the overlap of the C/AC pair's l_g. Its touch and detachment replace the local
  ones (``edges = "profile"``); a pass whose profile misfits keeps them (``edges_note``).
- ``l_g`` (the paper's construction): the clockwise and anticlockwise passes at the same
  overlap and speed each start contact on opposite sides of the lower sphere, before any
  viscous lag, so ``l_g`` is the distance between the two first touches and the centre of
  ``l_g`` is their midpoint (lab-frame ``theta``).
- ``mu``: ``F_h / F_v`` at the centre of ``l_g``, each force from a second-degree polynomial
  fitted to the 20 samples either side of the centre (there ``F_h = mu F_perp`` and
  ``F_v = F_perp``), per pass with its standard error (the centre's and the polynomials');
  the mean of C and AC cancels an error of the centre to first order, and hides it, so
  both are reported.
- Outliers: a pass is flagged, with the reason, when an edge fell back to its crossing,
  met samples beyond :data:`SPIKE_SIGMA`, or is uncertain, or when its mu disagrees with its
  partner's or its l_g with the other speeds' by more than :data:`OUTLIER_SE` s.e.
- Zero-crossing offset: travel from the centre of ``l_g`` to where ``F_h`` changes sign between
  its peak and its trough, positive towards detachment (the model puts it at ``mu h``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.noise import resolution_step, robust_sigma
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.sliding import SlidingGeometry

BoolArray = NDArray[np.bool_]

#: R1 + R2 (m) of the paper's shear rig: the onset model's default geometry.
S_PAPER = paper.R1_SHEAR + paper.R2_SHEAR

#: Fraction of the moving part of a pass, from its start, that sets the baseline and noise.
BASELINE_FRACTION = 0.1
#: Contact threshold in units of the baseline noise.
K_SIGMA = 5.0
#: Below-threshold samples that may interrupt one contact (near the F_h zero crossing).
MERGE_GAP = 5
#: Travel (m) of the first-touch window before and after the touch (docs/decisions/0260).
ONSET_BEFORE = 0.25e-3
ONSET_AFTER = 0.30e-3
#: Travel (m) of the detachment window before and after the end of contact.
DETACH_BEFORE = 0.35e-3
DETACH_AFTER = 0.30e-3
#: Degree of the polynomial in the travel left before detachment.
DETACH_DEGREE = 2
#: Robust loss of the edge fits: Huber, residuals in units of the noise.
EDGE_F_SCALE = 1.5
#: A residual beyond this many sigma in an edge window counts as a spike (down-weighted).
SPIKE_SIGMA = 5.0
#: Fewest samples in contact within an edge window for a fit.
EDGE_MIN_CONTACT = 4
#: A fitted edge farther than this (m) from its threshold crossing is not believed.
EDGE_REACH = 0.2e-3
#: An edge with a larger standard error (m) flags its pass.
EDGE_STDERR_FLAG = 6e-6
#: A pass whose mu, l_g or l_c disagrees with its level's by more than this many standard
#: errors is flagged.
OUTLIER_SE = 4.0
#: Columns of the whole-pass profile (:func:`profile_basis`): delta^1.5 and its integrals.
PROFILE_TERMS = 3
#: Points of the grid the profile's integrals are tabulated on, over the chord.
PROFILE_GRID = 20001
#: Largest excess of the profile's sum of squared residuals (units of the noise) over a
#: local edge fit's, in that edge's window, before the profile is refused. On the twin's
#: noise it stays below 29 over 800 passes (median 4); MDR unloading gives 900 and more.
PROFILE_MISFIT = 50.0
#: Profile fits per pair: the first at the overlap of the local touches' l_g, the next at
#: the overlap of the profile's.
PROFILE_ROUNDS = 2
#: Samples either side of the centre of l_g for the friction polynomial (the paper's 20).
CENTRE_POINTS = 20
#: A pass recorded over less than this fraction of the planned travel is truncated.
MIN_TRAVEL_FRACTION = 0.9
#: Columns a ladder step records that this module reads.
PASS_COLUMNS = ("t_s", "angle_rad", "torque_Nm", "normal_force_N", "gap_m", "pass",
                "direction", "speed_m_s", "overlap_m")


@dataclass(frozen=True)
class RecordedPass:
    """The samples of one pass (SI units); ``direction`` +1 clockwise, -1 anticlockwise."""

    index: int
    direction: float
    speed: float
    overlap: float
    t: FloatArray
    angle: FloatArray
    torque: FloatArray
    normal_force: FloatArray
    gap: FloatArray


def split_passes(columns: Mapping[str, FloatArray]) -> list[RecordedPass]:
    """The passes of a ladder step's columns, in recorded order (labels ``pass >= 0``)."""
    missing = [c for c in PASS_COLUMNS if c not in columns]
    if missing:
        raise ConfigError("columns", ", ".join(missing), "missing from the ladder data")
    label = np.asarray(columns["pass"], dtype=float)
    out = []
    for k in np.unique(label[label >= 0]).astype(int).tolist():
        m = label == k
        first = int(np.argmax(m))
        out.append(RecordedPass(
            index=k,
            direction=float(columns["direction"][first]),
            speed=float(columns["speed_m_s"][first]),
            overlap=float(columns["overlap_m"][first]),
            t=columns["t_s"][m], angle=columns["angle_rad"][m],
            torque=columns["torque_Nm"][m], normal_force=columns["normal_force_N"][m],
            gap=columns["gap_m"][m],
        ))
    return out


@dataclass(frozen=True)
class PassForces:
    """A pass's forces after the baseline: lab ``theta`` (m), F_h (moving frame), F_v (N)."""

    theta: FloatArray
    f_h: FloatArray
    f_v: FloatArray
    moving: BoolArray
    torque_baseline: float
    normal_baseline: float
    noise_h: float
    noise_v: float
    baseline_end: int


def moving_mask(p: RecordedPass, arm: float) -> BoolArray:
    """Samples taken while the arm turns at (at least half) the pass speed. A record repeated
    at the same time (the instrument's stream may carry one twice) takes its first's rate."""
    first = np.r_[True, np.diff(p.t) > 0] if p.t.size else np.zeros(0, dtype=bool)
    t, angle = p.t[first], p.angle[first]
    if t.size < 2:
        return np.zeros(p.t.size, dtype=bool)
    rate = (np.gradient(angle, t) * arm * p.direction)[np.cumsum(first) - 1]
    return np.asarray(rate > 0.5 * p.speed, dtype=bool)


def _noise(f: FloatArray, window: NDArray[np.intp], moving: NDArray[np.intp], index: int
           ) -> float:
    """Noise of ``f`` on the baseline ``window``; a quantised, nearly noise-free record has at
    least one resolution step (of the window, else of the whole moving part)."""
    noise = max(robust_sigma(f[window]), resolution_step(f[window]))
    if not noise > 0:
        noise = resolution_step(f[moving])
    if not noise > 0:
        raise ConfigError(f"pass {index}", "constant force", "no noise or resolution to scale by")
    return noise


def pass_forces(p: RecordedPass, arm: float) -> PassForces:
    """Baseline-corrected F_h and F_v of a pass, with their noise."""
    moving = moving_mask(p, arm)
    idx = np.flatnonzero(moving)
    if idx.size < 20:
        raise ConfigError(f"pass {p.index}", idx.size, "too few samples while the arm turned")
    window = idx[: max(10, int(BASELINE_FRACTION * idx.size))]
    m0 = float(np.median(p.torque[window]))
    n0 = float(np.median(p.normal_force[window]))
    f_h = p.direction * (p.torque - m0) / arm
    f_v = p.normal_force - n0
    noise_h, noise_v = _noise(f_h, window, idx, p.index), _noise(f_v, window, idx, p.index)
    return PassForces(p.angle * arm, f_h, f_v, moving, m0, n0, noise_h, noise_v,
                      int(window[-1]))


def _crossing(x: FloatArray, y: FloatArray, i: int, level: float) -> float:
    """Position where ``y`` crosses ``level`` between samples i-1 and i (linear)."""
    if i <= 0:
        return float(x[0])
    y0, y1 = float(y[i - 1]), float(y[i])
    frac = 0.0 if y1 == y0 else (level - y0) / (y1 - y0)
    return float(x[i - 1] + min(max(frac, 0.0), 1.0) * (x[i] - x[i - 1]))


@dataclass(frozen=True)
class PassResult:
    """What one pass shows; lengths and positions in m (lab theta), forces in N.

    ``l_g``, ``centre``, ``mu``, ``zero_offset`` come from pairing with the opposite pass
    (:func:`pair_passes`) and are NaN until then or when there is no partner.
    """

    index: int
    direction: float
    speed: float
    overlap: float
    contact_start: float
    contact_end: float
    l_c: float
    f_h_peak: float
    theta_peak: float
    f_h_trough: float
    theta_trough: float
    theta_zero: float
    f_v_peak: float
    noise_h: float
    noise_v: float
    travel: float
    l_g: float = math.nan
    centre: float = math.nan
    zero_offset: float = math.nan
    f_h_centre: float = math.nan
    f_v_centre: float = math.nan
    mu: float = math.nan
    #: First-contact position (m, lab theta) from the onset fit; NaN if not found.
    touch: float = math.nan
    touch_stderr: float = math.nan
    #: Where contact ended (m, lab theta) from the detachment fit; NaN if not found.
    detach: float = math.nan
    detach_stderr: float = math.nan
    #: Standard error of ``mu`` from the centre's (first order, m).
    mu_stderr: float = math.nan
    #: Why this pass is an outlier or was analysed with a fallback; empty when clean.
    flags: tuple[str, ...] = ()
    #: The local edge fits (first touch, detachment) the whole-pass profile starts from.
    local_edges: tuple[EdgeFit, EdgeFit] | None = None
    #: How ``touch`` and ``detach`` were found: "profile" (:func:`fit_profile`) or "local"
    #: (the edge windows alone; ``edges_note`` says why the profile was not used).
    edges: str = "local"
    edges_note: str = ""
    #: Standard error of ``l_c`` (m) from the profile fit (its edges are correlated).
    profile_l_c_stderr: float = math.nan

    @property
    def first_contact(self) -> float:
        """Where contact began (m, lab theta): ``touch``, else the threshold crossing."""
        return self.touch if math.isfinite(self.touch) else self.contact_start

    @property
    def last_contact(self) -> float:
        """Where contact ended (m, lab theta): ``detach``, else the threshold crossing."""
        return self.detach if math.isfinite(self.detach) else self.contact_end

    @property
    def local_l_c(self) -> float:
        """l_c (m) from the local edge fits alone (their threshold crossings where they fell
        back), before the whole-pass profile."""
        if self.local_edges is None:
            return self.l_c
        touch, detach = self.local_edges
        return abs((detach.position if detach.ok else self.contact_end)
                   - (touch.position if touch.ok else self.contact_start))

    @property
    def l_c_stderr(self) -> float:
        """Standard error of l_c (m): the profile fit's, else from the two local edges' (NaN
        when either fell back)."""
        if math.isfinite(self.profile_l_c_stderr):
            return self.profile_l_c_stderr
        return math.hypot(self.touch_stderr, self.detach_stderr)

    @property
    def ratio(self) -> float:
        """l_c / l_g."""
        return self.l_c / self.l_g if self.l_g > 0 else math.nan

    def row(self) -> dict[str, Any]:
        """A flat table row in SI units (column names carry the unit)."""
        return {
            "pass": self.index, "direction": self.direction, "speed_m_s": self.speed,
            "overlap_m": self.overlap, "contact_start_m": self.contact_start,
            "contact_end_m": self.contact_end, "l_c_m": self.l_c, "l_g_m": self.l_g,
            "l_c_over_l_g": self.ratio, "f_h_peak_N": self.f_h_peak,
            "f_h_trough_N": self.f_h_trough, "f_v_peak_N": self.f_v_peak,
            "theta_zero_m": self.theta_zero, "zero_offset_m": self.zero_offset,
            "centre_m": self.centre, "f_h_centre_N": self.f_h_centre,
            "f_v_centre_N": self.f_v_centre, "mu": self.mu, "mu_stderr": self.mu_stderr,
            "touch_m": self.touch, "touch_stderr_m": self.touch_stderr,
            "detach_m": self.detach, "detach_stderr_m": self.detach_stderr,
            "l_c_stderr_m": self.l_c_stderr, "edges": self.edges, "edges_note": self.edges_note,
            "outlier": bool(self.flags), "flags": "; ".join(self.flags),
        }


def contact_span(
    theta: FloatArray, f_h: FloatArray, f_v: FloatArray, thr_h: float, thr_v: float,
    moving: BoolArray | None = None,
) -> tuple[float, float, int, int] | None:
    """(start, end, i_first, i_last) of contact in theta, or None if the forces never rise."""
    signal = np.maximum(np.abs(f_h) / thr_h, f_v / thr_v)
    above = signal > 1.0
    if moving is not None:
        above &= moving
    idx = np.flatnonzero(above)
    if idx.size == 0:
        return None
    # Contact is one block of samples above the threshold; isolated excursions (a spike, the
    # drag vanishing as the arm stops) form other blocks. Keep the block with most signal.
    gap = max(MERGE_GAP, theta.size // 100)
    cuts = np.flatnonzero(np.diff(idx) > gap)
    blocks = np.split(idx, cuts + 1)
    best = max(blocks, key=lambda b: float(np.sum(signal[b])))
    i0, i1 = int(best[0]), int(best[-1])
    start = _crossing(theta, signal, i0, 1.0)
    end = _crossing(theta[::-1], signal[::-1], theta.size - 1 - i1, 1.0)
    return start, end, i0, i1


@dataclass(frozen=True)
class EdgeFit:
    """A contact edge (first touch or detachment) fitted over a window of travel.

    ``position`` is lab theta (m), NaN when not fitted (``reason`` says why); ``stderr`` (m)
    its standard error; ``samples`` in the window, ``spikes`` of them beyond
    :data:`SPIKE_SIGMA` (down-weighted by the robust loss); ``window`` that window (travel in
    the direction of motion, m) and ``mean_square`` the fit's mean squared residual there
    (units of the noise).
    """

    position: float = math.nan
    stderr: float = math.nan
    samples: int = 0
    spikes: int = 0
    reason: str = ""
    window: tuple[float, float] = (math.nan, math.nan)
    mean_square: float = math.nan

    @property
    def ok(self) -> bool:
        return math.isfinite(self.position)


#: Shape columns of F_h and F_v at travel ``x`` for an edge; both broadcast (``x[None, :]``
#: against ``edge[:, None]`` gives one block of columns per candidate edge).
Basis = Callable[[Any, Any], tuple[FloatArray, FloatArray]]


def onset_basis(overlap: float, s: float) -> Basis:
    """F_h and F_v shapes at first touch (one column each): Hertz ``F_perp = A delta^1.5``
    at the instantaneous modulus along the geometry of physics.md section 2 (``h = S -
    overlap``, ``psi = psi0 - u``, ``delta = S - hypot(h, psi)``), resolved as ``F_h ~ psi/d``
    and ``F_v ~ h/d``; ``u`` the travel past the touch (zero force before it)."""
    h = s - overlap
    psi0 = math.sqrt(max(s * s - h * h, 0.0))

    def basis(x: Any, edge: Any) -> tuple[FloatArray, FloatArray]:
        psi = psi0 - np.clip(x - edge, 0.0, None)
        d = np.hypot(h, psi)
        base = np.clip(s - d, 0.0, None) ** 1.5 / d
        return (base * psi)[..., None], (base * h)[..., None]

    return basis


def detach_basis(x: Any, edge: Any) -> tuple[FloatArray, FloatArray]:
    """F_h and F_v shapes at detachment: under the cutoff F_perp falls to zero with a finite
    slope, so each force is ``B v + C v^2`` in the travel ``v`` left before the edge."""
    v = np.clip(edge - x, 0.0, None)
    cols = np.stack([v ** (k + 1) for k in range(DETACH_DEGREE)], axis=-1)
    return cols, cols


def _design(cols: FloatArray) -> FloatArray:
    """The shape columns, each scaled to unit peak, with a constant offset column."""
    peak = np.max(np.abs(cols), axis=-2, keepdims=True)
    return np.concatenate([cols / np.where(peak > 0, peak, 1.0),
                           np.ones((*cols.shape[:-1], 1))], axis=-1)


def _scan(x: FloatArray, y_h: FloatArray, y_v: FloatArray, basis: Basis,
          edges: FloatArray) -> float:
    """The edge of ``edges`` whose linear least-squares fit leaves the least residual (all
    candidates at once: ``basis`` broadcasts over an edge column)."""
    ssr = np.zeros(edges.size)
    for cols, y in zip(basis(x[None, :], edges[:, None]), (y_h, y_v), strict=True):
        a = _design(cols)
        ata = np.einsum("mnk,mnl->mkl", a, a)
        ata += 1e-12 * np.eye(ata.shape[-1]) * np.trace(ata, axis1=1, axis2=2)[:, None, None]
        coef = np.linalg.solve(ata, np.einsum("mnk,n->mk", a, y)[..., None])[..., 0]
        ssr += np.sum((y - np.einsum("mnk,mk->mn", a, coef)) ** 2, axis=1)
    return float(edges[int(np.argmin(ssr))])


def fit_edge(x: FloatArray, y_h: FloatArray, y_v: FloatArray, basis: Basis,
             lo: float, hi: float, step: float) -> tuple[float, float, FloatArray]:
    """Fit an edge at travel ``x`` (m, increasing) to F_h and F_v in units of their noise.

    The model is ``basis`` times free amplitudes plus a free offset per force; the edge is
    scanned over ``[lo, hi]`` in ``step`` and refined with a Huber loss
    (``scipy.optimize.least_squares``). Returns (edge, standard error, normalised
    residuals); the error is NaN when the fit does not determine it.
    """
    from scipy.optimize import least_squares

    edge0 = _scan(x, y_h, y_v, basis, np.arange(lo, hi + step / 2, step))
    scale = max(step, 1e-7)
    c_h, c_v = basis(x, edge0)
    peak_h = np.max(np.abs(c_h), axis=0)
    peak_v = np.max(np.abs(c_v), axis=0)
    k = c_h.shape[1]
    start = []
    for cols, y in ((c_h, y_h), (c_v, y_v)):
        coef, *_ = np.linalg.lstsq(_design(cols), y, rcond=None)
        start.extend(coef.tolist())

    def residuals(p: FloatArray) -> FloatArray:
        e = edge0 + p[0] * scale
        g_h, g_v = basis(x, e)
        m_h = (g_h / np.where(peak_h > 0, peak_h, 1.0)) @ p[1:1 + k] + p[1 + k]
        m_v = (g_v / np.where(peak_v > 0, peak_v, 1.0)) @ p[2 + k:2 + 2 * k] + p[2 + 2 * k]
        return np.concatenate([y_h - m_h, y_v - m_v])

    lower = np.full(len(start) + 1, -np.inf)
    upper = np.full(len(start) + 1, np.inf)
    lower[0], upper[0] = (lo - step - edge0) / scale, (hi + step - edge0) / scale
    res = least_squares(residuals, np.r_[0.0, start], loss="huber", f_scale=EDGE_F_SCALE,
                        bounds=(lower, upper), diff_step=1e-3)
    edge = edge0 + float(res.x[0]) * scale
    if not lo - step / 2 <= edge <= hi + step / 2:
        return math.nan, math.nan, res.fun
    jac = res.jac
    try:
        cov = np.linalg.inv(jac.T @ jac)
        spread = max(1.0, 1.4826 * float(np.median(np.abs(res.fun - np.median(res.fun)))))
        stderr = math.sqrt(max(float(cov[0, 0]), 0.0)) * scale * spread
    except np.linalg.LinAlgError:
        stderr = math.nan
    return edge, stderr, res.fun


def _edge(f: PassForces, direction: float, crossing: float, basis: Basis, before: float,
          after: float, contact_side: float) -> EdgeFit:
    """Fit one edge near the threshold ``crossing`` (lab theta, m), windowed by travel:
    ``before`` and ``after`` (m) either side of the edge, refitted once around the fit."""
    x_all = direction * f.theta
    y_h, y_v = f.f_h / f.noise_h, f.f_v / f.noise_v
    x_c = direction * crossing
    spacing = float(np.median(np.abs(np.diff(x_all[f.moving])))) if np.count_nonzero(
        f.moving) > 1 else 1e-6
    step = min(max(spacing / 2.0, 5e-7), 2e-6)
    centre = x_c
    fit: EdgeFit = EdgeFit(reason="no fit")
    for _ in range(2):
        w = f.moving & (x_all >= centre - before) & (x_all <= centre + after)
        x = x_all[w]
        inside = np.count_nonzero(contact_side * (x - centre) > 0)
        if inside < EDGE_MIN_CONTACT or x.size - inside < EDGE_MIN_CONTACT:
            return EdgeFit(samples=int(x.size), reason=f"{inside} samples in contact within "
                           f"the {(before + after) * 1e3:.2f} mm window")
        # A noise excursion merged into the contact block moves the crossing either way.
        lo, hi = max(x_c - EDGE_REACH, float(x[0])), min(x_c + EDGE_REACH, float(x[-1]))
        if not hi > lo:
            return EdgeFit(samples=int(x.size), reason="window does not hold the crossing")
        edge, stderr, resid = fit_edge(x, y_h[w], y_v[w], basis, lo, hi, step)
        if not math.isfinite(edge):
            return EdgeFit(samples=int(x.size), reason="the edge fit left its range")
        fit = EdgeFit(direction * edge, stderr, int(x.size),
                      int(np.count_nonzero(np.abs(resid) > SPIKE_SIGMA)),
                      window=(float(x[0]), float(x[-1])),
                      mean_square=float(np.mean(resid ** 2)))
        if abs(edge - centre) < 0.25 * min(before, after):
            break
        centre = edge
    return fit


def first_touch(f: PassForces, direction: float, crossing: float, overlap: float,
                s: float) -> EdgeFit:
    """Where the pass first touched (lab theta, m): the onset model (:func:`onset_basis`)
    fitted to F_h and F_v over :data:`ONSET_BEFORE` / :data:`ONSET_AFTER` of travel around
    the threshold ``crossing``."""
    return _edge(f, direction, crossing, onset_basis(overlap, s), ONSET_BEFORE, ONSET_AFTER,
                 1.0)


def detachment(f: PassForces, direction: float, crossing: float) -> EdgeFit:
    """Where contact ended (lab theta, m): :func:`detach_basis` fitted over
    :data:`DETACH_BEFORE` / :data:`DETACH_AFTER` of travel around the last crossing."""
    return _edge(f, direction, crossing, detach_basis, DETACH_BEFORE, DETACH_AFTER, -1.0)


@dataclass(frozen=True)
class ProfileFit:
    """Both edges of a pass from its whole in-contact profile (:func:`fit_profile`).

    Positions are lab theta (m), NaN when the fit failed or did not match the data (``reason``
    says why); ``l_c_stderr`` (m) is that of their distance (the two are correlated);
    ``misfit`` the larger excess of its sum of squared residuals (units of the noise) over
    a local edge fit's, in that edge's window.
    """

    touch: float = math.nan
    touch_stderr: float = math.nan
    detach: float = math.nan
    detach_stderr: float = math.nan
    l_c_stderr: float = math.nan
    misfit: float = math.nan
    reason: str = ""

    @property
    def ok(self) -> bool:
        return math.isfinite(self.touch) and math.isfinite(self.detach)


def profile_basis(overlap: float, s: float) -> tuple[Callable[[FloatArray], FloatArray],
                                                          float, float]:
    """The fresh-contact shape of F_perp along a pass as :data:`PROFILE_TERMS` columns of the
    travel ``u`` past the touch: ``x = delta^1.5`` (physics.md section 1, ``delta`` along the
    geometry of section 2 with ``h = s - overlap``) and its repeated integrals over ``u``.

    At constant speed ``v`` the hereditary integral of an exponential kernel is ``x -
    X_1 / (v tau) + X_2 / (v tau)^2 - ...``, so any Prony series is a combination of these
    columns while ``u / (v tau)`` is small (the paper's 2000 s: below 0.23 over the longest
    chord at the slowest speed; three terms leave less than 1 um of l_c). Each column is
    scaled to a unit peak; zero before the touch. Returns (columns, h, psi0)."""
    h = s - overlap
    psi0 = math.sqrt(max(s * s - h * h, 0.0))
    grid = np.linspace(0.0, 2.0 * psi0, PROFILE_GRID)
    step = float(grid[1] - grid[0])
    terms = [np.clip(s - np.hypot(h, psi0 - grid), 0.0, None) ** 1.5]
    for _ in range(PROFILE_TERMS - 1):
        prev = terms[-1]
        terms.append(np.r_[0.0, np.cumsum(0.5 * (prev[1:] + prev[:-1]) * step)])
    peaks = [float(np.max(t)) or 1.0 for t in terms]

    def columns(u: FloatArray) -> FloatArray:
        inside = np.clip(u, 0.0, 2.0 * psi0)
        first = np.clip(s - np.hypot(h, psi0 - inside), 0.0, None) ** 1.5 / peaks[0]
        rest = [np.interp(inside, grid, t) / p for t, p in zip(terms[1:], peaks[1:],
                                                                strict=True)]
        return np.stack([first, *rest], axis=-1) * (u > 0)[..., None]

    return columns, h, psi0


def _profile_residuals(x: FloatArray, y_h: FloatArray, y_v: FloatArray,
                       columns: Callable[[FloatArray], FloatArray], h: float, psi0: float,
                       touch: float, detach: float, m_h: float, m_v: float
                       ) -> tuple[FloatArray, FloatArray]:
    """Residuals of F_h and F_v (units of their noise) for the profile with edges ``touch``
    and ``detach`` (travel, m) and friction terms ``m_h``, ``m_v``; amplitudes and offsets
    by linear least squares."""
    u = x - touch
    cols = columns(u)
    at_end = columns(np.array([detach - touch]))[0]
    if not at_end[0] > 0:  # detachment beyond the chord: no such profile
        return np.full(x.size, 1e3), np.full(x.size, 1e3)
    # F_perp is a combination of the columns that is zero at detachment (the cutoff), and
    # zero beyond it.
    shape = (cols[:, 1:] - np.outer(cols[:, 0], at_end[1:] / at_end[0])) * (
        (u < detach - touch)[:, None])
    psi = psi0 - u
    d = np.hypot(h, psi)
    ones = np.ones((x.size, 1))
    out: list[FloatArray] = []
    for y, resolve in ((y_h, (psi + m_h * h) / d), (y_v, (h - m_v * psi) / d)):
        a = np.hstack([shape * resolve[:, None], ones])
        ata = a.T @ a
        try:
            coef = np.linalg.solve(ata + 1e-12 * np.trace(ata) * np.eye(ata.shape[0]), a.T @ y)
        except np.linalg.LinAlgError:
            coef = np.linalg.lstsq(a, y, rcond=None)[0]
        out.append(y - a @ coef)
    return out[0], out[1]


def fit_profile(f: PassForces, direction: float, touch: EdgeFit, detach: EdgeFit,
                overlap: float, s: float, start: tuple[float, float] | None = None
                ) -> ProfileFit:
    """Both edges of a pass fitted to its whole in-contact F_h and F_v (docs/decisions/0260,
    addendum): the fresh-contact shape of :func:`profile_basis` at ``overlap`` (m; the pair's,
    from its l_g), resolved as physics.md section 2 with a free friction term per force, each
    force with its own free amplitudes and offset, zero outside [touch, detachment].

    Spans the windows of the local edge fits ``touch`` and ``detach`` and starts from them
    (or from ``start``, lab theta of both edges, m). The edges and friction terms are fitted
    with the Huber loss of the edge fits, the amplitudes by linear least squares at each
    step. Refused (NaN, with the reason) when the profile fits an edge window worse than the
    local fit by more than :data:`PROFILE_MISFIT` (chi^2): then the data do not have the
    cutoff model's shape (e.g. MDR unloading, carried history) and the local edges stand."""
    from scipy.optimize import least_squares

    if not (touch.ok and detach.ok) or not 0 < overlap < s:
        return ProfileFit(reason="no local edges or overlap to start from")
    x_all = direction * f.theta
    e1, e2 = direction * touch.position, direction * detach.position
    w = f.moving & (x_all >= e1 - ONSET_BEFORE) & (x_all <= e2 + DETACH_AFTER)
    if start is not None:
        e1, e2 = direction * start[0], direction * start[1]
    x = x_all[w]
    y_h, y_v = f.f_h[w] / f.noise_h, f.f_v[w] / f.noise_v
    columns, h, psi0 = profile_basis(overlap, s)
    if not e2 - e1 < 2.0 * psi0:
        return ProfileFit(reason=f"the local l_c ({(e2 - e1) * 1e3:.4f} mm) is not inside the "
                          f"chord of the pair's l_g ({2e3 * psi0:.4f} mm)")
    scale = 1e-6

    def residuals(p: FloatArray) -> FloatArray:
        r_h, r_v = _profile_residuals(x, y_h, y_v, columns, h, psi0, e1 + p[0] * scale,
                                      e2 + p[1] * scale, p[2] * 1e-2, p[3] * 1e-2)
        return np.concatenate([r_h, r_v])

    reach = EDGE_REACH / scale
    # Edges in um from the start, friction terms in 1e-2 (from the paper's 5e-3).
    res = least_squares(residuals, np.array([0.0, 0.0, 0.5, 0.5]), loss="huber",
                        f_scale=EDGE_F_SCALE, diff_step=1e-4, xtol=1e-4, ftol=1e-5)
    if not (res.success and np.all(np.isfinite(res.fun))):
        return ProfileFit(reason=f"the profile fit failed: {res.message}")
    if not np.all(np.abs(res.x[:2]) <= reach):
        return ProfileFit(reason=f"the profile's edges moved beyond {EDGE_REACH * 1e3:g} mm")
    edge1, edge2 = e1 + float(res.x[0]) * scale, e2 + float(res.x[1]) * scale
    # Misfit: the squared residuals in each local edge window against the local fit's there.
    excess = []
    for local in (touch, detach):
        near = np.tile((x >= local.window[0]) & (x <= local.window[1]), 2)
        excess.append(float(np.sum(res.fun[near] ** 2) - local.mean_square
                            * np.count_nonzero(near)) if np.any(near) else math.inf)
    misfit = max(excess)
    if not misfit <= PROFILE_MISFIT:
        return ProfileFit(misfit=misfit, reason=f"the whole-pass profile fits an edge window "
                          f"worse than the local fit, chi^2 +{misfit:.3g} (beyond "
                          f"{PROFILE_MISFIT:g}): the local edges stand")
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac)
    except np.linalg.LinAlgError:
        return ProfileFit(reason="the profile fit does not determine its edges")
    spread = max(1.0, 1.4826 * float(np.median(np.abs(res.fun - np.median(res.fun)))))
    cov = cov[:2, :2] * (scale * spread) ** 2
    l_c_var = float(cov[0, 0] + cov[1, 1] - 2.0 * cov[0, 1])
    return ProfileFit(direction * edge1, math.sqrt(max(float(cov[0, 0]), 0.0)),
                      direction * edge2, math.sqrt(max(float(cov[1, 1]), 0.0)),
                      math.sqrt(max(l_c_var, 0.0)), misfit)


def analyse_pass(p: RecordedPass, arm: float, k_sigma: float = K_SIGMA, s: float = S_PAPER
                 ) -> PassResult:
    """Contact span, l_c, F_h peak and trough, zero crossing of one pass (no pairing);
    ``s`` = R1 + R2 (m) shapes the onset model."""
    f = pass_forces(p, arm)
    travel = float(np.ptp(f.theta[f.moving])) if np.any(f.moving) else 0.0
    span = contact_span(f.theta, f.f_h, f.f_v, k_sigma * f.noise_h, k_sigma * f.noise_v,
                        f.moving)
    if span is None:
        raise ConfigError(f"pass {p.index}", "no contact",
                          f"the forces never rose {k_sigma:g} sigma above the baseline")
    start, end, i0, i1 = span
    if i0 <= f.baseline_end:
        raise ConfigError(f"pass {p.index}", "contact in the baseline window",
                          "the leg must start clear of contact (no baseline)")
    inside = slice(i0, i1 + 1)
    seg_h = f.f_h[inside]
    ip = int(np.argmax(seg_h))
    it = int(np.argmin(seg_h))
    theta_zero = math.nan
    if it > ip:  # last + to - sign change between the peak and the trough
        between = seg_h[ip : it + 1]
        changes = np.flatnonzero((between[:-1] > 0) & (between[1:] <= 0))
        if changes.size:
            j = i0 + ip + int(changes[-1]) + 1
            theta_zero = _crossing(f.theta, f.f_h, j, 0.0)
    touch = first_touch(f, p.direction, start, p.overlap, s)
    detach = detachment(f, p.direction, end)
    flags = []
    for what, edge, fallback in (("first touch", touch, "threshold crossing"),
                                 ("detachment", detach, "last threshold crossing")):
        if not edge.ok:
            flags.append(f"{what} from the {fallback}: {edge.reason}")
            continue
        if edge.spikes:
            flags.append(f"{what}: {edge.spikes} sample(s) beyond {SPIKE_SIGMA:g} sigma in its "
                         "window, down-weighted")
        if not edge.stderr <= EDGE_STDERR_FLAG:
            flags.append(f"{what} uncertain: s.e. {edge.stderr * 1e6:.1f} um")
    first = touch.position if touch.ok else start
    last = detach.position if detach.ok else end
    return PassResult(
        index=p.index, direction=p.direction, speed=p.speed, overlap=p.overlap,
        contact_start=start, contact_end=end,
        l_c=abs(last - first),
        f_h_peak=float(seg_h[ip]), theta_peak=float(f.theta[i0 + ip]),
        f_h_trough=float(seg_h[it]), theta_trough=float(f.theta[i0 + it]),
        theta_zero=theta_zero, f_v_peak=float(np.max(f.f_v[inside])),
        noise_h=f.noise_h, noise_v=f.noise_v, travel=travel, touch=touch.position,
        touch_stderr=touch.stderr, detach=detach.position, detach_stderr=detach.stderr,
        flags=tuple(flags), local_edges=(touch, detach),
    )


def chord_overlap(l_g: float, s: float) -> float:
    """The overlap (m) whose chord ``2 sqrt(s^2 - (s - overlap)^2)`` is ``l_g`` (m); NaN
    outside (0, 2 s)."""
    if not 0 < l_g < 2.0 * s:
        return math.nan
    return s - math.sqrt(s * s - 0.25 * l_g * l_g)


def refine_edges(passes: Sequence[RecordedPass], results: Sequence[PassResult], arm: float,
                 s: float = S_PAPER) -> list[PassResult]:
    """Each C/AC pair's edges from the whole in-contact profile (:func:`fit_profile`).

    The shape depends on the overlap, which the rig knows only to the contact search's
    error: it is taken from the pair's l_g (the chord, physics.md section 2), first that of
    the local touches, then that of the profile's (:data:`PROFILE_ROUNDS`). Each pass keeps
    its own edges, amplitudes and friction; a pass without a partner, or whose profile
    misfits, keeps its local edges and says why in ``edges_note``."""
    by_index = {p.index: p for p in passes}
    groups: dict[tuple[float, float], dict[float, PassResult]] = {}
    for r in results:
        groups.setdefault((round(r.overlap, 9), r.speed), {}).setdefault(r.direction, r)
    refined: dict[int, PassResult] = {}
    for pair in groups.values():
        cw, acw = pair.get(1.0), pair.get(-1.0)
        if cw is None or acw is None:
            continue
        forces = {r.index: pass_forces(by_index[r.index], arm) for r in (cw, acw)}
        current = {r.index: r for r in (cw, acw)}
        for _ in range(PROFILE_ROUNDS):
            c, a = current[cw.index], current[acw.index]
            overlap = chord_overlap(a.first_contact - c.first_contact, s)
            fits = {r.index: fit_profile(forces[r.index], r.direction, *r.local_edges,
                                         overlap, s, (current[r.index].touch,
                                                      current[r.index].detach))
                    for r in (cw, acw) if r.local_edges is not None}
            if len(fits) < 2 or not all(fit.ok for fit in fits.values()):
                notes = "; ".join(f"pass {i}: {f.reason}" for i, f in fits.items()
                                  if not f.ok) or "no local edges to start from"
                current = {r.index: replace(r, edges="local", edges_note=notes)
                           for r in (cw, acw)}
                break
            current = {i: replace(
                current[i], touch=fit.touch, touch_stderr=fit.touch_stderr, detach=fit.detach,
                detach_stderr=fit.detach_stderr, l_c=abs(fit.detach - fit.touch),
                profile_l_c_stderr=fit.l_c_stderr, edges="profile",
                edges_note=f"overlap {overlap * 1e3:.4f} mm from l_g; misfit {fit.misfit:+.2f}")
                for i, fit in fits.items()}
        refined.update(current)
    return [refined.get(r.index) or replace(
        r, edges_note="no opposite pass at its level to take the overlap from")
        for r in results]


def value_at(theta: FloatArray, y: FloatArray, centre: float,
             points: int = CENTRE_POINTS) -> float:
    """``y`` at ``centre`` from a second-degree polynomial over ``points`` samples each side."""
    return value_and_stderr(theta, y, centre, 0.0, points)[0]


def value_and_stderr(theta: FloatArray, y: FloatArray, centre: float, noise: float,
                     points: int = CENTRE_POINTS) -> tuple[float, float]:
    """:func:`value_at` and its standard error for white noise ``noise`` on ``y``."""
    i = int(np.searchsorted(theta, centre)) if theta[-1] >= theta[0] else \
        theta.size - int(np.searchsorted(theta[::-1], centre))
    lo, hi = max(0, i - points), min(theta.size, i + points)
    if hi - lo < 5:
        return math.nan, math.nan
    x = theta[lo:hi] - centre
    coef = np.polyfit(x, y[lo:hi], 2)
    a = np.vander(x / max(float(np.max(np.abs(x))), 1e-12), 3)
    c00 = float(np.linalg.pinv(a.T @ a)[-1, -1])
    return float(coef[-1]), noise * math.sqrt(max(c00, 0.0))


def friction_at_centre(
    p: RecordedPass, arm: float, centre: float, points: int = CENTRE_POINTS
) -> tuple[float, float]:
    """(F_h, F_v) at lab position ``centre`` (m) from the paper's local polynomials."""
    f = pass_forces(p, arm)
    idx = np.flatnonzero(f.moving)
    theta, f_h, f_v = f.theta[idx], f.f_h[idx], f.f_v[idx]
    return value_at(theta, f_h, centre, points), value_at(theta, f_v, centre, points)


def _slope_at(theta: FloatArray, y: FloatArray, centre: float, half: float) -> float:
    """d y / d theta at ``centre`` from a line over ``half`` (m) of travel each side."""
    w = np.abs(theta - centre) <= half
    if np.count_nonzero(w) < 3:
        return math.nan
    return float(np.polyfit(theta[w] - centre, y[w], 1)[0])


def pair_passes(
    passes: Sequence[RecordedPass], results: Sequence[PassResult], arm: float,
    points: int = CENTRE_POINTS,
) -> list[PassResult]:
    """Fill l_g, centre, mu (with its standard error from the centre's) and the
    zero-crossing offset from C/AC pairs at one overlap and speed (the first clockwise and
    the first anticlockwise pass of each pair of levels), and flag a pair whose mu_C and
    mu_AC disagree by more than :data:`OUTLIER_SE` standard errors."""
    by_index = {p.index: p for p in passes}
    groups: dict[tuple[float, float], dict[float, PassResult]] = {}
    for r in results:
        groups.setdefault((round(r.overlap, 9), r.speed), {}).setdefault(r.direction, r)
    out = []
    for r in results:
        pair = groups[(round(r.overlap, 9), r.speed)]
        cw, acw = pair.get(1.0), pair.get(-1.0)
        if cw is None or acw is None:
            out.append(r)
            continue
        l_g = acw.first_contact - cw.first_contact
        centre = 0.5 * (acw.first_contact + cw.first_contact)
        f = pass_forces(by_index[r.index], arm)
        idx = np.flatnonzero(f.moving)
        theta, f_h = f.theta[idx], f.f_h[idx]
        f_h_c, se_h = value_and_stderr(theta, f_h, centre, f.noise_h, points)
        f_v_c, se_v = value_and_stderr(theta, f.f_v[idx], centre, f.noise_v, points)
        offset = r.direction * (r.theta_zero - centre)
        mu = f_h_c / f_v_c if f_v_c > 0 else math.nan
        se_centre = 0.5 * math.hypot(cw.touch_stderr, acw.touch_stderr)
        # mu's standard error: the centre's (through F_h's slope there) and the polynomials'.
        mu_se = math.hypot(_slope_at(theta, f_h, centre, 0.25 * abs(l_g)) * se_centre, se_h,
                           mu * se_v) / f_v_c if f_v_c > 0 else math.nan
        out.append(replace(r, l_g=l_g, centre=centre, zero_offset=offset, f_h_centre=f_h_c,
                           f_v_centre=f_v_c, mu=mu, mu_stderr=mu_se))
    return _flag_levels(out)


def _flag_levels(results: list[PassResult]) -> list[PassResult]:
    """Flag passes that disagree with their level: mu_C against mu_AC, and l_g against the
    median over the speeds at the same overlap, beyond :data:`OUTLIER_SE` standard errors."""
    by_level: dict[tuple[float, float], list[PassResult]] = {}
    by_overlap: dict[float, list[float]] = {}
    for r in results:
        by_level.setdefault((round(r.overlap, 9), r.speed), []).append(r)
        if r.direction > 0 and math.isfinite(r.l_g):
            by_overlap.setdefault(round(r.overlap, 9), []).append(r.l_g)
    out = []
    for r in results:
        flags = list(r.flags)
        group = by_level[(round(r.overlap, 9), r.speed)]
        other = [o for o in group if o.direction != r.direction]
        if other and math.isfinite(r.mu) and math.isfinite(other[0].mu):
            diff = r.mu - other[0].mu
            se = math.hypot(r.mu_stderr, other[0].mu_stderr)
            if se > 0 and abs(diff) > OUTLIER_SE * se:
                flags.append(f"mu C and AC differ by {abs(diff):.2g} ({abs(diff) / se:.1f} s.e.):"
                             " the centre of l_g is off")
        l_gs = by_overlap.get(round(r.overlap, 9), [])
        se_lg = math.hypot(*(o.touch_stderr for o in group)) if len(group) == 2 else math.nan
        if len(l_gs) >= 3 and math.isfinite(r.l_g) and se_lg > 0:
            dev = r.l_g - float(np.median(l_gs))
            if abs(dev) > OUTLIER_SE * max(se_lg, 1e-6):
                flags.append(f"l_g differs from the overlap's median over speeds by "
                             f"{dev * 1e6:+.1f} um ({abs(dev) / se_lg:.1f} s.e.)")
        out.append(replace(r, flags=tuple(flags)) if len(flags) != len(r.flags) else r)
    return out


@dataclass(frozen=True)
class LadderAnalysis:
    """Every analysed pass, and what could not be analysed (one line each)."""

    results: list[PassResult]
    problems: list[str]

    def levels(self) -> list[dict[str, float]]:
        """One row per (overlap, speed): l_g, l_c (C, AC), mean l_c/l_g, mu (C, AC, mean).

        The C and AC means of mu and of the zero offset are the estimates: an error ``e`` of
        the centre of l_g shifts the two passes' values by +e and -e (first order), which
        the mean cancels. Per-pass values keep that error.
        """
        keys = sorted({(round(r.overlap, 9), r.speed) for r in self.results})
        rows = []
        for overlap, speed in keys:
            group = [r for r in self.results if round(r.overlap, 9) == overlap
                     and r.speed == speed]
            cw = [r for r in group if r.direction > 0]
            acw = [r for r in group if r.direction < 0]
            rows.append({
                "overlap_m": overlap, "speed_m_s": speed,
                "l_g_m": group[0].l_g,
                "l_c_C_m": cw[0].l_c if cw else math.nan,
                "l_c_AC_m": acw[0].l_c if acw else math.nan,
                "l_c_over_l_g": float(np.mean([r.ratio for r in group])),
                "mu_C": cw[0].mu if cw else math.nan,
                "mu_AC": acw[0].mu if acw else math.nan,
                "mu": 0.5 * (cw[0].mu + acw[0].mu) if cw and acw else math.nan,
                "zero_offset_m": float(np.nanmean([r.zero_offset for r in group]))
                if any(math.isfinite(r.zero_offset) for r in group) else math.nan,
            })
        return rows


def analyse_ladder(
    columns: Mapping[str, FloatArray], arm: float, travel: float | None = None,
    k_sigma: float = K_SIGMA, s: float = S_PAPER,
) -> tuple[LadderAnalysis, list[RecordedPass]]:
    """Analyse every complete pass of a ladder step; truncated or contact-free passes are
    reported in ``problems`` and left out. ``travel`` (m) is the planned leg travel, ``s``
    R1 + R2 (m)."""
    passes = split_passes(columns)
    good: list[RecordedPass] = []
    results: list[PassResult] = []
    problems: list[str] = []
    for p in passes:
        try:
            r = analyse_pass(p, arm, k_sigma, s)
        except ConfigError as exc:
            problems.append(f"pass {p.index}: {exc.allowed}; skipped")
            continue
        if travel is not None and r.travel < MIN_TRAVEL_FRACTION * travel:
            problems.append(f"pass {p.index} is truncated ({r.travel * 1e3:.2f} mm of "
                            f"{travel * 1e3:.2f} mm recorded); skipped")
            continue
        good.append(p)
        results.append(r)
    unpaired = []
    paired = pair_passes(good, refine_edges(good, results, arm, s), arm)
    for r in paired:
        if not math.isfinite(r.l_g):
            unpaired.append(r.index)
    if unpaired:
        problems.append("no opposite pass at the same overlap and speed for pass(es) "
                        f"{', '.join(map(str, unpaired))}: no l_g or mu there")
    return LadderAnalysis(paired, problems), good


def geometric_l_g(
    s: float, touch_gap: float, passes: Sequence[RecordedPass], results: Sequence[PassResult],
    overlap: float, speed: float,
) -> float:
    """Geometric contact length ``2 sqrt(S^2 - h^2)`` (m) at one (overlap, speed) level.

    ``S = R1 + R2`` (m); ``h = S - (touch_gap - gap)`` with ``gap`` the mean over that level's
    passes of each one's median recorded gap in its middle half. A check on the measured l_g
    once a model fit has pinned the touch gap; NaN when no pass is at that level.
    """
    gaps = [float(np.median(p.gap[p.gap.size // 4: 3 * p.gap.size // 4]))
            for p, r in zip(passes, results, strict=True)
            if round(r.overlap, 9) == overlap and r.speed == speed]
    if not gaps:
        return math.nan
    h = s - (touch_gap - float(np.mean(gaps)))
    return 2.0 * math.sqrt(max(s * s - h * h, 0.0))


def chord(r1: float, r2: float, overlap: float) -> float:
    """The chord ``2 psi0`` (m): the geometric contact length of spheres ``r1``, ``r2`` (m)
    passing at ``overlap`` (m) below the touch gap
    (:attr:`gelrig.instrument.physics.sliding.SlidingGeometry.
    l_g`); NaN for an overlap that is not in (0, R1 + R2).

    The ladder sets ``gap = touch_gap - overlap`` with the touch gap its contact search found,
    so at the step's overlap setpoint this is the l_g the measured one should equal.
    """
    try:
        return SlidingGeometry(r1, r2, overlap).l_g
    except ConfigError:
        return math.nan


def with_chords(rows: Sequence[Mapping[str, float]], r1: float, r2: float
                ) -> list[dict[str, float]]:
    """Table rows (per pass or per level, each with ``overlap_m``, ``l_g_m`` and ``l_c*``)
    with ``l_g_chord_m`` (the chord at the overlap setpoint) and ``l_g_over_chord``."""
    out = []
    for row in rows:
        c = chord(r1, r2, float(row["overlap_m"]))
        out.append({**row, "l_g_chord_m": c,
                    "l_g_over_chord": float(row["l_g_m"]) / c if c > 0 else math.nan})
    return out
