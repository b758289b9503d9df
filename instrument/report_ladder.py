"""The report's part for a speed-ladder step: figures, tables and summary lines.

Formatting only: every number comes from :mod:`instrument.ladder_analysis`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from instrument.contact import FloatArray
from instrument.ladder_analysis import LadderModel, LadderStep
from instrument.model_fit import FitSetup, ModelFit, describe_setup
from instrument.report import Column, Section, Table
from instrument.report_plots import (
    FitPanel,
    PassCurve,
    plot_fit_grid,
    plot_pass_curves,
    plot_vs_speed,
)
from instrument.shear_analysis import PassResult, with_chords

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
    Column("contact_start_m", "contact start (mm)", 1e3, 6),
    Column("contact_end_m", "contact end (mm)", 1e3, 6),
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
)
_DEFINITIONS = (
    "l_c: first rise to return to baseline (5 sigma of the pre-contact noise, F_h or F_v); "
    "l_g: between the first-contact points of the clockwise and anticlockwise passes at the "
    "same overlap and speed; chord: 2 sqrt(S^2 - (S - delta)^2), S = R1 + R2, the geometric "
    "l_g at the step's overlap setpoint delta below the touch gap the contact search found "
    "(what l_g should equal, at every speed); mu: F_h/F_v at the centre of l_g (second-degree "
    "polynomials over 20 samples each side), averaged over C and AC, which cancels an error "
    "of the centre to first order. Definitions: docs/decisions/0030-analysis-definitions.md."
)


def _level(r: PassResult) -> float:
    return round(r.overlap, 9)


def ladder_section(
    ladder: LadderStep, levels: list[dict[str, float]], model: LadderModel | None,
    index: int, name: str, setup: FitSetup, out: Path,
) -> Section:
    """The report section of an analysed ladder (``levels`` with their chords,
    :func:`instrument.shear_analysis.with_chords`); its figures are written to ``out``."""
    results = ladder.analysis.results
    section = Section(f"Shear: {name} (step {index})", [
        f"{len(results)} passes analysed; arm {setup.arm * 1e3:g} mm, R1 "
        f"{setup.r1 * 1e3:g} mm, R2 {setup.r2 * 1e3:g} mm. {_DEFINITIONS}"])
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
                     (r.contact_start, r.contact_end) if marks else ())


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
                              "dotted: contact start and end of each (l_c)."))
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


def ladder_summary(ladder: LadderStep, levels: Sequence[dict[str, float]],
                   fit: ModelFit | None, index: int, name: str,
                   setup: FitSetup | None = None) -> list[str]:
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
                  f"  {'':<26s}mu       " + cells("mu", 1.0, ".4f")]
    if fit is not None:
        lines += _fit_summary(fit, setup)
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
    lines = [f"  model fit to all passes ({model}{fit.n_points} points per force, "
             f"{fit.seconds:.1f} s), 95 % CI:"]
    lines += ["    " + "; ".join(parts[i:i + 2]) for i in range(0, len(parts), 2)]
    lines.append(f"    rms residual F_h {fit.rms_h * 1e3:.4f} mN (noise "
                 f"{fit.noise_h * 1e3:.4f}), F_v {fit.rms_v * 1e3:.4f} mN (noise "
                 f"{fit.noise_v * 1e3:.4f})")
    return lines
