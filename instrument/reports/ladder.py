"""The report's part for a speed-ladder step: figures, tables and summary lines.

Formatting only: every number comes from :mod:`gelrig.instrument.analysis.ladder_analysis`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.instrument.analysis.ladder_analysis import LadderModel, LadderStep
from gelrig.instrument.analysis.model_fit import FitSetup, ModelFit, describe_setup
from gelrig.instrument.analysis.shear_analysis import PassResult, with_chords
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.reports.document import Column, Section, Table
from gelrig.instrument.reports.figures import (
    FitPanel,
    PassCurve,
    plot_fit_grid,
    plot_pass_curves,
    plot_vs_speed,
)

#: Margin drawn either side of a pass's contact in the model-fit figures (fraction of l_c).
PANEL_PAD = 0.15

_PASS_COLUMNS = (
    Column("pass", "pass"), Column("direction", "dir"), Column("speed_m_s", "v (m/s)", digits=3),
    Column("overlap_m", "overlap (mm)", 1e3), Column("l_c_m", "l_c (mm)", 1e3),
    Column("l_g_m", "l_g (mm)", 1e3), Column("l_g_chord_m", "chord (mm)", 1e3),
    Column("l_c_over_l_g", "l_c/l_g"), Column("f_h_peak_N", "F_h peak (mN)", 1e3),
    Column("f_h_trough_N", "F_h trough (mN)", 1e3),
    Column("f_v_peak_N", "F_v peak (mN)", 1e3),
    Column("zero_offset_m", "zero offset (um)", 1e6, 3), Column("mu", "mu", digits=3),
    Column("mu_stderr", "mu s.e.", digits=2),
    Column("touch_m", "first touch (mm)", 1e3, 7),
    Column("touch_stderr_m", "touch s.e. (um)", 1e6, 2),
    Column("detach_m", "detachment (mm)", 1e3, 7),
    Column("detach_stderr_m", "detachment s.e. (um)", 1e6, 2),
    Column("l_c_stderr_m", "l_c s.e. (um)", 1e6, 2), Column("edges", "edges from"),
    Column("edges_note", "edges note"),
    Column("contact_start_m", "contact start (mm)", 1e3, 6),
    Column("contact_end_m", "contact end (mm)", 1e3, 6),
    Column("outlier", "outlier"), Column("flags", "why flagged"),
)
_LEVEL_COLUMNS = (
    Column("overlap_m", "overlap (mm)", 1e3), Column("speed_m_s", "v (m/s)", digits=3),
    Column("l_g_m", "l_g (mm)", 1e3), Column("l_g_chord_m", "chord at the set overlap (mm)", 1e3),
    Column("l_g_over_chord", "l_g/chord"), Column("l_g_geom_m", "l_g geometric, fit (mm)", 1e3),
    Column("l_c_C_m", "l_c C (mm)", 1e3), Column("l_c_AC_m", "l_c AC (mm)", 1e3),
    Column("l_c_over_l_g", "mean l_c/l_g"), Column("mu_C", "mu C", digits=3),
    Column("mu_AC", "mu AC", digits=3), Column("mu", "mu (C+AC)/2", digits=3),
    Column("zero_offset_m", "zero offset (um)", 1e6, 3),
)
_FIT_COLUMNS = (
    Column("parameter", "parameter"), Column("value", "value", digits=6),
    Column("stderr", "std. error", digits=3), Column("ci95_lo", "95 % low", digits=6),
    Column("ci95_hi", "95 % high", digits=6), Column("unit", "unit"),
    Column("interval", "interval"),
)
_DEFINITIONS = (
    "l_c: from first touch to detachment, each fitted over a window of travel (the onset "
    "model's F_h, F_v ~ delta^1.5 along the sliding geometry; a polynomial falling to zero at "
    "detachment) with a robust loss, the 5 sigma threshold crossings as the fallback, then "
    "both refined by a fit of the pass's whole in-contact F_h and F_v to the fresh-contact "
    "shape at the overlap of the pair's l_g (edges from: profile; local where that misfits); "
    "l_g: between the first-contact points of the clockwise and anticlockwise passes at the "
    "same overlap and speed; chord: 2 sqrt(S^2 - (S - delta)^2), S = R1 + R2, the geometric "
    "l_g at the step's overlap setpoint delta below the touch gap the contact search found "
    "(what l_g should equal, at every speed); mu: F_h/F_v at the centre of l_g (second-degree "
    "polynomials over 20 samples each side), per pass (C and AC; their mean cancels an error "
    "of the centre to first order, and hides it); a pass is flagged with the reason when an "
    "edge fit fell back or met spikes, or its mu or l_g disagrees with its level's. "
    "Definitions: docs/decisions/0030-analysis-definitions.md, 0260."
)


def _level(r: PassResult) -> float:
    return round(r.overlap, 9)


def ladder_section(
    ladder: LadderStep, levels: list[dict[str, float]], model: LadderModel | None,
    index: int, name: str, setup: FitSetup, out: Path,
    search: Mapping[str, Any] | None = None,
) -> Section:
    """The report section of an analysed ladder (``levels`` with their chords,
    :func:`gelrig.instrument.analysis.shear_analysis.with_chords`); its figures are written to
    ``out``."""
    results = ladder.analysis.results
    section = Section(f"Shear: {name} (step {index})", [
        f"{len(results)} passes analysed; arm {setup.arm * 1e3:g} mm, R1 "
        f"{setup.r1 * 1e3:g} mm, R2 {setup.r2 * 1e3:g} mm. {_DEFINITIONS}",
        *(f"Warning: {w}." for w in ladder_warnings(ladder, model.fit if model else None,
                                                    search))])
    prefix = f"ladder_{index:02d}"
    section.figures += _pass_figures(ladder, out, prefix)
    section.figures += _speed_figures(levels, model.fit if model else None, out, prefix)
    if model is not None:
        section.figures += _model_figures(ladder, model, out, prefix)
    if model is not None:
        section.tables.append(Table("Model fit to all passes (SI; 95 % confidence intervals; "
                                    f"{describe_setup(setup)})",
                                    _FIT_COLUMNS, model.fit.rows(), f"{prefix}_model_fit.csv"))
    section.tables += [
        Table("Per (overlap, speed)", _LEVEL_COLUMNS, levels, f"{prefix}_levels.csv"),
        Table("Per pass", _PASS_COLUMNS,
              with_chords([r.row() for r in results], setup.r1, setup.r2),
              f"{prefix}_passes.csv"),
    ]
    return section


def _curve(ladder: LadderStep, r: PassResult, label: str, marks: bool = True) -> PassCurve:
    f = ladder.forces[r.index]
    m = f.moving
    return PassCurve(label, f.theta[m], f.f_h[m], f.f_v[m],
                     (r.first_contact, r.last_contact) if marks else ())


def _pass_figures(ladder: LadderStep, out: Path, prefix: str) -> list[tuple[str, str]]:
    """F_h and F_v of chosen passes: the C/AC pair at the deepest overlap and slowest speed,
    then the clockwise passes along each speed and each overlap."""
    results = ladder.analysis.results
    deepest = max(_level(r) for r in results)
    slowest = min(r.speed for r in results)
    figures = []
    pair = [r for r in results if _level(r) == deepest and r.speed == slowest]
    if pair:
        centre = pair[0].centre if math.isfinite(pair[0].centre) else 0.0
        curves = [_curve(ladder, r, f"{'C' if r.direction > 0 else 'AC'}: l_c "
                                    f"{r.l_c * 1e3:.3f} mm") for r in pair]
        name = f"{prefix}_C_AC.png"
        plot_pass_curves(out / name, curves, f"overlap {deepest * 1e3:.2f} mm, "
                         f"{slowest:.3g} m/s: l_g {pair[0].l_g * 1e3:.3f} mm", centre)
        figures.append((name, "F_h and F_v of the clockwise and anticlockwise passes; "
                              "dotted: first touch and detachment of each (l_c)."))
    clockwise = [r for r in results if r.direction > 0]
    for chosen, title, name, caption, label in (
        ([r for r in clockwise if _level(r) == deepest],
         f"overlap {deepest * 1e3:.2f} mm", f"{prefix}_speeds.png",
         "Clockwise passes at the deepest overlap, one per speed.",
         lambda r: f"{r.speed:.3g} m/s"),
        ([r for r in clockwise if r.speed == slowest],
         f"speed {slowest:.3g} m/s", f"{prefix}_overlaps.png",
         "Clockwise passes at the slowest speed, one per overlap.",
         lambda r: f"{r.overlap * 1e3:.2f} mm"),
    ):
        if not chosen:
            continue
        centres = [r.centre for r in chosen]
        centre = float(np.nanmedian(centres)) if any(map(math.isfinite, centres)) else 0.0
        curves = [_curve(ladder, r, label(r), marks=False) for r in chosen]
        plot_pass_curves(out / name, curves, f"clockwise, {title}", centre)
        figures.append((name, caption))
    return figures


def _by_overlap(levels: Sequence[dict[str, float]], key: str
                ) -> dict[str, tuple[FloatArray, FloatArray]]:
    """``key`` against speed, one series per overlap (label in mm)."""
    overlaps = sorted({r["overlap_m"] for r in levels})
    return {f"{o * 1e3:.2f} mm": (
        np.array([r["speed_m_s"] for r in levels if r["overlap_m"] == o]),
        np.array([r[key] for r in levels if r["overlap_m"] == o])) for o in overlaps}


def _speed_figures(levels: Sequence[dict[str, float]], fit: ModelFit | None, out: Path,
                   prefix: str) -> list[tuple[str, str]]:
    """l_c/l_g and mu against speed, one line per overlap."""
    plot_vs_speed(out / f"{prefix}_lc_lg.png", _by_overlap(levels, "l_c_over_l_g"), "l_c / l_g",
                  "deformed over geometric contact length", 1.0, "l_c = l_g")
    plot_vs_speed(out / f"{prefix}_mu.png", _by_overlap(levels, "mu"),
                  "mu = F_h / F_v at the centre of l_g", "friction coefficient",
                  fit.mu if fit else None, f"model fit mu {fit.mu:.4g}" if fit else "")
    return [(f"{prefix}_lc_lg.png", "l_c/l_g (mean of C and AC) against speed, "
                                    "one line per overlap."),
            (f"{prefix}_mu.png", "Friction coefficient against speed, one line "
                                 "per overlap; dashed: the model fit.")]


def _model_figures(ladder: LadderStep, model: LadderModel, out: Path,
                   prefix: str) -> list[tuple[str, str]]:
    """Every pass's F_h and F_v around its contact against the model fitted to all at once."""
    results = ladder.analysis.results
    order = sorted(results, key=lambda r: (_level(r), r.speed, -r.direction))
    panels_h, panels_v = [], []
    for r in order:
        f = ladder.forces[r.index]
        where = np.flatnonzero(model.trajectory.pass_index == r.index)
        lo, hi = sorted((r.contact_start, r.contact_end))
        pad = PANEL_PAD * (hi - lo)
        win = f.moving & (f.theta > lo - pad) & (f.theta < hi + pad)
        title = f"{r.overlap * 1e3:.2f} mm {r.speed:.2g} {'C' if r.direction > 0 else 'AC'}"
        panels_h.append(FitPanel(title, f.theta[win], f.f_h[win], model.f_h[where][win]))
        panels_v.append(FitPanel(title, f.theta[win], f.f_v[win], model.f_v[where][win]))
    cols = 2 * len({r.speed for r in results})
    figures = []
    for kind, panels, ylabel in (("fh", panels_h, "F_h (mN)"), ("fv", panels_v, "F_v (mN)")):
        name = f"{prefix}_model_{kind}.png"
        plot_fit_grid(out / name, panels, cols, ylabel,
                      f"{ylabel[:3]}: data (grey) and the fitted model (red)")
        figures.append((name, f"{ylabel[:3]} of every pass against the model fitted to "
                              "all passes at once."))
    return figures


#: The smallest overlap should exceed the touch gap's standard error this many times.
OVERLAP_RESOLUTION_FACTOR = 10.0


def touch_gap_stderr(search: Mapping[str, Any]) -> float:
    """Standard error (m) of the contact search's touch gap from its line through the
    square roots of the peak torques against the gap (``touch_fit`` in its results); NaN
    without three points or a falling line."""
    fit = search.get("touch_fit") or {}
    gaps = np.asarray(fit.get("gaps_m") or [], dtype=float)
    root = np.sqrt(np.clip(np.asarray(fit.get("peak_torque_Nm") or [], dtype=float), 0, None))
    if gaps.size < 3 or gaps.size != root.size:
        return math.nan
    (slope, icpt), cov = np.polyfit(gaps, root, 1, cov="unscaled")
    resid = root - (slope * gaps + icpt)
    s2 = float(np.sum(resid ** 2)) / max(gaps.size - 2, 1)
    if not slope < 0:
        return math.nan
    # x0 = -icpt / slope; its variance by the delta method
    g = np.array([icpt / slope ** 2, -1.0 / slope])
    return math.sqrt(max(float(g @ (cov * s2) @ g), 0.0))


def ladder_warnings(ladder: LadderStep, fit: ModelFit | None,
                    search: Mapping[str, Any] | None = None) -> list[str]:
    """Where the per-pass recipe is known to be biased: mu = F_h/F_v at the centre of l_g when
    the fit finds F_h and F_v with different moduli (the ratio then carries F_perp_h /
    F_perp_v), and overlaps near the touch gap's resolution."""
    out = []
    if fit is not None:
        names = {e.name for e in fit.estimates}
        for k in range(1, 10):
            if f"G_{k}_h" not in names or f"G_{k}_v" not in names:
                break
            h, v = fit.estimate(f"G_{k}_h"), fit.estimate(f"G_{k}_v")
            if h.hi < v.lo or v.hi < h.lo:
                out.append(f"F_h and F_v have different moduli (G_{k}_h {h.value:.4g} Pa, "
                           f"G_{k}_v {v.value:.4g} Pa, 95 % intervals apart): mu = F_h/F_v at "
                           "the centre of l_g is biased by their ratio; the model fit's mu "
                           f"({fit.mu:.4g}) is the estimate")
                break
    se = touch_gap_stderr(search or {})
    overlaps = [r.overlap for r in ladder.analysis.results]
    if overlaps and math.isfinite(se) and min(overlaps) < OVERLAP_RESOLUTION_FACTOR * se:
        least = min(overlaps)
        out.append(f"the smallest overlap ({least * 1e3:.3f} mm) is within "
                   f"{OVERLAP_RESOLUTION_FACTOR:g}x the touch gap's standard error "
                   f"({se * 1e6:.1f} um): the chord at the set overlap is uncertain by "
                   f"{50 * se / least:.2g} % or more")
    return out


def ladder_summary(ladder: LadderStep, levels: Sequence[dict[str, float]],
                   fit: ModelFit | None, index: int, name: str,
                   setup: FitSetup | None = None,
                   search: Mapping[str, Any] | None = None) -> list[str]:
    """The stdout summary's lines for a ladder: per overlap the chord at the set overlap and,
    per speed, the measured l_g, l_c/l_g and mu; then the fit."""
    speeds = sorted({r["speed_m_s"] for r in levels})
    overlaps = sorted({r["overlap_m"] for r in levels})
    lines = [f"Shear ladder, step {index} ({name}): {len(ladder.analysis.results)} "
             f"passes, {len(overlaps)} overlaps x {len(speeds)} speeds; chord = l_g of the "
             "geometry at the set overlap",
             f"  {'speed (m/s)':<35s}" + "".join(f"{v:>10.2e}" for v in speeds)]
    for o in overlaps:
        row = {r["speed_m_s"]: r for r in levels if r["overlap_m"] == o}
        chord = next((r.get("l_g_chord_m", math.nan) for r in row.values()), math.nan)

        def cells(key: str, scale: float, fmt: str, row: dict = row) -> str:
            return "".join(f"{row[v][key] * scale:>10{fmt}}" if v in row else f"{'-':>10s}"
                           for v in speeds)

        lines += [f"  {o * 1e3:.2f} mm  chord {chord * 1e3:6.3f} mm  l_g (mm) "
                  + cells("l_g_m", 1e3, ".3f"),
                  f"  {'':<26s}l_c/l_g  " + cells("l_c_over_l_g", 1.0, ".4f"),
                  f"  {'':<26s}mu C     " + cells("mu_C", 1.0, ".4f"),
                  f"  {'':<26s}mu AC    " + cells("mu_AC", 1.0, ".4f")]
    lines += _outlier_lines(ladder.analysis.results)
    if fit is not None:
        lines += _fit_summary(fit, setup)
    lines += [f"  WARNING: {w}" for w in ladder_warnings(ladder, fit, search)]
    return lines


def _outlier_lines(results: Sequence[PassResult], most: int = 8) -> list[str]:
    """The flagged passes with their reasons (up to ``most``; the report lists all)."""
    flagged = [r for r in results if r.flags]
    if not flagged:
        return [f"  outliers: none of {len(results)} passes flagged"]
    lines = [f"  outliers: {len(flagged)} of {len(results)} passes flagged:"]
    for r in flagged[:most]:
        lines.append(f"    pass {r.index} ({r.overlap * 1e3:.2f} mm, {r.speed:.3g} m/s, "
                     f"{'C' if r.direction > 0 else 'AC'}): {'; '.join(r.flags)}")
    if len(flagged) > most:
        lines.append(f"    ... and {len(flagged) - most} more (passes.csv, column flags)")
    return lines


def _fit_summary(fit: ModelFit, setup: FitSetup | None = None) -> list[str]:
    """The model fit's estimates with their 95 % intervals, two a line, and its residuals."""
    parts = []
    for e in fit.estimates:
        if e.name == "lower_angle":
            parts.append(f"lower angle {e.value:.5f} rad [{e.lo:.5f}, {e.hi:.5f}]")
        elif e.name == "touch_gap":
            parts.append(f"touch gap {e.value * 1e3:.4f} mm [{e.lo * 1e3:.4f}, "
                         f"{e.hi * 1e3:.4f}]")
        elif e.name == "mu":
            parts.append(f"mu {e.value:.4g} [{e.lo:.4g}, {e.hi:.4g}]")
        else:
            parts.append(f"{e.name} {e.value:.5g} {e.unit} [{e.lo:.5g}, {e.hi:.5g}]")
    model = "" if setup is None else f"{describe_setup(setup)}; "
    profiled = [e.name for e in fit.estimates if e.interval == "profile"]
    how = (f"profile likelihood for {', '.join(profiled)}, linearised otherwise"
           if profiled else "linearised")
    lines = [f"  model fit to all passes ({model}{fit.n_points} points per force, "
             f"{fit.seconds:.1f} s), 95 % CI ({how}):"]
    lines += ["    " + "; ".join(parts[i:i + 2]) for i in range(0, len(parts), 2)]
    lines.append(f"    rms residual F_h {fit.rms_h * 1e3:.4f} mN (noise "
                 f"{fit.noise_h * 1e3:.4f}), F_v {fit.rms_v * 1e3:.4f} mN (noise "
                 f"{fit.noise_v * 1e3:.4f})")
    return lines


def joint_fit_summary(fit: ModelFit, steps: Sequence[int], setup: FitSetup) -> list[str]:
    """The summary's lines for the model fitted to the passes of several ladder steps."""
    return [f"Joint model fit, ladder steps {', '.join(map(str, steps))} together "
            f"({fit.n_passes} passes):", *_fit_summary(fit, setup)]


def joint_fit_section(fit: ModelFit, steps: Sequence[int], setup: FitSetup) -> Section:
    """The report section of the model fitted to the passes of several ladder steps at once
    (a ladder split over steps), beside each step's own fit."""
    return Section(
        f"Shear: one model fit to ladder steps {', '.join(map(str, steps))} together",
        [f"All {fit.n_passes} passes of the {len(steps)} ladder steps fitted with one "
         f"parameter set ({describe_setup(setup)}); the motion of every shear step in time "
         "order drives the model, each pass a fresh contact. 95 % confidence intervals."],
        [], [Table("Joint model fit (SI; 95 % confidence intervals)", _FIT_COLUMNS, fit.rows(),
                   "ladder_joint_model_fit.csv")])
