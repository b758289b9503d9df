"""Per-pass quantities of a recorded sliding-speed ladder (paper, section "Results").

Definitions (docs/decisions/0030):

- Forces: ``F_h = s (M - M_0) / L`` in the frame of the motion (``s`` = +1 clockwise, -1
  anticlockwise; docs/decisions/0022) and ``F_v = N - N_0``; the baselines ``M_0`` and ``N_0``
  are medians over the first :data:`BASELINE_FRACTION` of the moving part of the pass, well
  before contact, so the bearing drag and any normal-force offset drop out.
- Contact: a sample is in contact when ``|F_h|`` or ``F_v`` exceeds :data:`K_SIGMA` times its
  noise (:func:`instrument.noise.robust_sigma` of the baseline window). The deformed contact length
  ``l_c`` is the travel from the first touch (below) to the last such sample (the crossing
  interpolated linearly between samples).
- ``l_g`` (the paper's construction): the clockwise and anticlockwise passes at the same
  overlap and speed each start contact on opposite sides of the lower sphere, before any
  viscous lag, so ``l_g`` is the distance between the two first-contact positions and the
  centre of ``l_g`` is their midpoint (lab-frame ``theta``). The first-contact position of a
  pass (``touch``) is where its rise extrapolates to zero force: at first touch
  ``F_h ~ (travel)^1.5`` (Hertz, before any relaxation), so ``F_h^(2/3)`` is a straight line
  in the travel, fitted between :data:`ONSET_LO` and :data:`ONSET_HI` sigma; the threshold
  crossing (``contact_start``) lies a noise-dependent distance later and is used when the fit
  fails (docs/decisions/0141).
- ``mu``: ``F_h / F_v`` at the centre of ``l_g``, each force from a second-degree polynomial
  fitted to the 20 samples either side of the centre (there ``F_h = mu F_perp`` and
  ``F_v = F_perp``); the estimate per (overlap, speed) is the mean of the C and AC passes,
  which cancels an error of the centre to first order.
- Zero-crossing offset: travel from the centre of ``l_g`` to where ``F_h`` changes sign between
  its peak and its trough, positive towards detachment (the model puts it at ``mu h``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from instrument.contact import FloatArray
from instrument.errors import ConfigError
from instrument.noise import resolution_step, robust_sigma
from instrument.sliding import SlidingGeometry

BoolArray = NDArray[np.bool_]

#: Fraction of the moving part of a pass, from its start, that sets the baseline and noise.
BASELINE_FRACTION = 0.1
#: Contact threshold in units of the baseline noise.
K_SIGMA = 5.0
#: Below-threshold samples that may interrupt one contact (near the F_h zero crossing).
MERGE_GAP = 5
#: F_h range (in units of its noise) of the first-touch line fit of F_h^(2/3) on the travel.
ONSET_LO = 3.0
ONSET_HI = 100.0
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
    # Quantised, nearly noise-free records: at least one resolution step.
    noise_h = max(robust_sigma(f_h[window]), resolution_step(f_h[window]))
    noise_v = max(robust_sigma(f_v[window]), resolution_step(f_v[window]))
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
    #: First-contact position (m, lab theta) extrapolated to zero force; NaN if not found.
    touch: float = math.nan

    @property
    def first_contact(self) -> float:
        """Where contact began (m, lab theta): ``touch``, else the threshold crossing."""
        return self.touch if math.isfinite(self.touch) else self.contact_start

    @property
    def ratio(self) -> float:
        """l_c / l_g."""
        return self.l_c / self.l_g if self.l_g > 0 else math.nan

    def row(self) -> dict[str, float]:
        """A flat table row in SI units (column names carry the unit)."""
        return {
            "pass": self.index, "direction": self.direction, "speed_m_s": self.speed,
            "overlap_m": self.overlap, "contact_start_m": self.contact_start,
            "contact_end_m": self.contact_end, "l_c_m": self.l_c, "l_g_m": self.l_g,
            "l_c_over_l_g": self.ratio, "f_h_peak_N": self.f_h_peak,
            "f_h_trough_N": self.f_h_trough, "f_v_peak_N": self.f_v_peak,
            "theta_zero_m": self.theta_zero, "zero_offset_m": self.zero_offset,
            "centre_m": self.centre, "f_h_centre_N": self.f_h_centre,
            "f_v_centre_N": self.f_v_centre, "mu": self.mu, "touch_m": self.touch,
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


def first_touch(f: PassForces, direction: float, i0: int, i1: int) -> float:
    """Lab theta (m) where F_h^(2/3), linear in the travel at first touch, reaches zero.

    Fitted over the samples from just before the threshold crossing ``i0`` to where F_h
    first exceeds ONSET_HI sigma, keeping those above ONSET_LO sigma; NaN when too few
    samples or the line does not rise.
    """
    sig = f.f_h / f.noise_h
    lo = max(0, i0 - 2 * MERGE_GAP)
    strong = np.flatnonzero(sig[i0:i1 + 1] > ONSET_HI)
    hi = i0 + int(strong[0]) if strong.size else i1
    w = np.arange(lo, hi + 1)
    w = w[(sig[w] > ONSET_LO) & f.moving[w]]
    if w.size < 3:
        return math.nan
    travel = direction * f.theta[w]
    slope, icpt = np.polyfit(travel, f.f_h[w] ** (2.0 / 3.0), 1)
    if not slope > 0:
        return math.nan
    touch = direction * (-icpt / slope)
    # The extrapolation stays near the crossing (a few samples' travel), else it failed.
    reach = 4.0 * abs(float(f.theta[hi] - f.theta[lo])) + 1e-9
    return float(touch) if abs(touch - float(f.theta[i0])) < reach else math.nan


def analyse_pass(p: RecordedPass, arm: float, k_sigma: float = K_SIGMA) -> PassResult:
    """Contact span, l_c, F_h peak and trough, zero crossing of one pass (no pairing)."""
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
    touch = first_touch(f, p.direction, i0, i1)
    return PassResult(
        index=p.index, direction=p.direction, speed=p.speed, overlap=p.overlap,
        contact_start=start, contact_end=end,
        l_c=abs(end - (touch if math.isfinite(touch) else start)),
        f_h_peak=float(seg_h[ip]), theta_peak=float(f.theta[i0 + ip]),
        f_h_trough=float(seg_h[it]), theta_trough=float(f.theta[i0 + it]),
        theta_zero=theta_zero, f_v_peak=float(np.max(f.f_v[inside])),
        noise_h=f.noise_h, noise_v=f.noise_v, travel=travel, touch=touch,
    )


def value_at(theta: FloatArray, y: FloatArray, centre: float,
             points: int = CENTRE_POINTS) -> float:
    """``y`` at ``centre`` from a second-degree polynomial over ``points`` samples each side."""
    i = int(np.searchsorted(theta, centre)) if theta[-1] >= theta[0] else \
        theta.size - int(np.searchsorted(theta[::-1], centre))
    lo, hi = max(0, i - points), min(theta.size, i + points)
    if hi - lo < 5:
        return math.nan
    x = theta[lo:hi] - centre
    coef = np.polyfit(x, y[lo:hi], 2)
    return float(coef[-1])


def friction_at_centre(
    p: RecordedPass, arm: float, centre: float, points: int = CENTRE_POINTS
) -> tuple[float, float]:
    """(F_h, F_v) at lab position ``centre`` (m) from the paper's local polynomials."""
    f = pass_forces(p, arm)
    idx = np.flatnonzero(f.moving)
    theta, f_h, f_v = f.theta[idx], f.f_h[idx], f.f_v[idx]
    return value_at(theta, f_h, centre, points), value_at(theta, f_v, centre, points)


def pair_passes(
    passes: Sequence[RecordedPass], results: Sequence[PassResult], arm: float,
    points: int = CENTRE_POINTS,
) -> list[PassResult]:
    """Fill l_g, centre, mu and the zero-crossing offset from C/AC pairs at one overlap and
    speed (the first clockwise and the first anticlockwise pass of each pair of levels)."""
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
        f_h_c, f_v_c = friction_at_centre(by_index[r.index], arm, centre, points)
        offset = r.direction * (r.theta_zero - centre)
        mu = f_h_c / f_v_c if f_v_c > 0 else math.nan
        out.append(replace(r, l_g=l_g, centre=centre, zero_offset=offset, f_h_centre=f_h_c,
                           f_v_centre=f_v_c, mu=mu))
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
    k_sigma: float = K_SIGMA,
) -> tuple[LadderAnalysis, list[RecordedPass]]:
    """Analyse every complete pass of a ladder step; truncated or contact-free passes are
    reported in ``problems`` and left out. ``travel`` (m) is the planned leg travel."""
    passes = split_passes(columns)
    good: list[RecordedPass] = []
    results: list[PassResult] = []
    problems: list[str] = []
    for p in passes:
        try:
            r = analyse_pass(p, arm, k_sigma)
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
    paired = pair_passes(good, results, arm)
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
    passing at ``overlap`` (m) below the touch gap (:attr:`instrument.sliding.SlidingGeometry.
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
