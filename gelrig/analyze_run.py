"""Turn a run directory into the paper's figures and numbers: ``analyze_run(run_dir, out_dir)``.

A composition root like the CLI (it reads the stored rig and protocol tables through their
parsers). It checks the run against its protocol, analyses whatever is complete, names
whatever is missing, and writes ``report.html`` with PNG figures and CSV tables:

- compression (``ramp_hold`` steps): G(t) over the hold, 1- and 2-term Prony fits with
  uncertainties, residuals;
- shear (``speed_ladder`` steps): per-pass l_c, l_g, F_h peak/trough, zero-crossing offset
  and mu (:mod:`instrument.shear_analysis`), l_c/l_g and mu against speed, and the
  ladder-wide model fit (:mod:`instrument.model_fit`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from instrument import paper
from instrument.analysis import MIN_HOLD_SAMPLES, RelaxationFit, fit_hold, modulus_history
from instrument.contact import FloatArray
from instrument.errors import ConfigError, GelrigError
from instrument.model_fit import FitSetup, ModelFit, Trajectory, fit_ladder, model_forces
from instrument.report import Column, Section, Table, write_report
from instrument.report_plots import (
    FitPanel,
    PassCurve,
    plot_fit_grid,
    plot_hold_fits,
    plot_pass_curves,
    plot_vs_speed,
)
from instrument.shear_analysis import (
    LadderAnalysis,
    PassResult,
    RecordedPass,
    analyse_ladder,
    pass_forces,
)
from instrument.store import RunDirectory, read_step


@dataclass(frozen=True)
class StepData:
    """A recorded step: its index, kind, name, status, parameters, results and columns."""

    index: int
    kind: str
    name: str
    status: str
    params: dict[str, Any]
    results: dict[str, Any]
    columns: dict[str, FloatArray]


@dataclass
class AnalysisResult:
    """What ``analyze_run`` produced: the report's path, the stdout summary, the problems."""

    run_dir: Path
    out_dir: Path
    report_path: Path
    summary: str
    problems: list[str]
    hold_fits: dict[int, list[RelaxationFit]] = field(default_factory=dict)
    ladders: dict[int, LadderAnalysis] = field(default_factory=dict)
    model_fits: dict[int, ModelFit] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        """True when nothing was missing or skipped."""
        return not self.problems


@dataclass
class _Context:
    run: RunDirectory
    out: Path
    meta: dict[str, Any]
    problems: list[str]
    sections: list[Section]
    summary: list[str]
    setup: FitSetup
    fit_model: bool


# -- reading the run -------------------------------------------------------------------------

def _planned_steps(meta: Mapping[str, Any], problems: list[str]) -> list[tuple[str, str, dict]]:
    """(kind, name, params) of every step the stored protocol planned."""
    from protocols.spec import parse_protocol

    table = meta.get("protocol")
    if not isinstance(table, dict):
        problems.append("run.json holds no protocol: analysing the recorded steps as found")
        return []
    try:
        spec = parse_protocol(table, "run.json protocol")
    except ConfigError as exc:
        problems.append(f"the stored protocol is not valid ({exc}); using the recorded steps")
        return []
    return [(s.kind, s.name, s.params.to_table()) for s in spec.steps]


def _arm(meta: Mapping[str, Any], problems: list[str]) -> float:
    from protocols.rigfile import ShearRigSpec, parse_rig

    try:
        rig = parse_rig(meta["rig"], "run.json rig")
        if not isinstance(rig, ShearRigSpec):
            raise ConfigError("rig.kind", rig.kind, "a shear rig has the rheometer arm")
        return float(rig.rheometer.config.arm)
    except (KeyError, TypeError, ConfigError) as exc:
        problems.append(f"no rheometer arm in the stored rig ({exc}); using the paper's "
                        f"{paper.ARM * 1e3:g} mm")
        return paper.ARM


def load_steps(run: RunDirectory, meta: Mapping[str, Any], problems: list[str]) -> list[StepData]:
    """Every readable step, in order; missing, unfinished or unreadable ones go to problems."""
    planned = _planned_steps(meta, problems)
    recorded = {int(s["index"]): s for s in meta.get("steps", [])}
    for s in meta.get("interrupted_steps", []):
        problems.append(f"step {s['index']} ({s['name']}): an interrupted attempt is kept in "
                        f"{s['file']}; the resumed attempt is analysed")
    indices = sorted(set(recorded) | set(range(len(planned))))
    out = []
    for i in indices:
        kind, name, params = planned[i] if i < len(planned) else ("?", f"step {i}", {})
        rec = recorded.get(i)
        if rec is None:
            problems.append(f"step {i} ({name}, {kind}) was never recorded: the run stopped "
                            "before it")
            continue
        kind, name = rec.get("kind", kind), rec.get("name", name)
        status = str(rec.get("status", "?"))
        path = run.path / str(rec.get("file", ""))
        if not path.is_file():
            problems.append(f"step {i} ({name}): data file {rec.get('file')} is missing")
            continue
        try:
            columns = read_step(path)
        except (OSError, KeyError, ValueError, GelrigError) as exc:
            problems.append(f"step {i} ({name}): data file {rec.get('file')} cannot be read "
                            f"({exc})")
            continue
        n = len(next(iter(columns.values()))) if columns else 0
        if status != "completed":
            problems.append(f"step {i} ({name}) is {status}, not completed: analysing the "
                            f"{n} samples recorded")
        out.append(StepData(i, kind, name, status, params, dict(rec.get("results") or {}),
                            columns))
    return out


# -- compression -----------------------------------------------------------------------------

def _hold(ctx: _Context, step: StepData) -> list[RelaxationFit]:
    cols = step.columns
    if not {"t_s", "force_N", "delta_m"} <= set(cols) or cols["t_s"].size < MIN_HOLD_SAMPLES:
        ctx.problems.append(f"step {step.index} ({step.name}): no hold data to fit")
        return []
    diameter = float(step.params.get("diameter", paper.DIAMETER_COMPRESSION))
    radius = diameter / 2
    depth = step.results.get("depth_m")
    if depth is None:
        depth = float(step.params.get("strain", paper.STRAIN_HOLD)) * diameter
    t, force, delta = cols["t_s"], cols["force_N"], cols["delta_m"]
    ok = np.isfinite(delta) & np.isfinite(force)
    t, force, delta = t[ok], force[ok], delta[ok]
    top = float(np.max(delta)) if delta.size else 0.0
    tol = 1e-4 * abs(top) + 1e-9
    held = np.flatnonzero(delta >= top - tol)
    if held.size < MIN_HOLD_SAMPLES or top < 0.9 * depth:
        ctx.problems.append(f"step {step.index} ({step.name}): the ramp never reached the "
                            f"hold depth {depth * 1e3:.3f} mm (deepest {top * 1e3:.3f} mm)")
        return []
    end = int(held[-1]) + 1  # the retract after the hold is not part of it
    t, force, delta = t[:end], force[:end], delta[:end]
    planned = float(step.params.get("hold", math.nan))
    recorded = float(t[-1] - t[int(held[0])])
    if math.isfinite(planned) and recorded < 0.98 * planned:
        ctx.problems.append(f"step {step.index} ({step.name}): hold recorded for "
                            f"{recorded:.0f} s of the planned {planned:.0f} s; fitting that")
    fits = []
    for terms in (1, 2):
        try:
            fits.append(fit_hold(t, force, radius, depth, terms=terms, delta=delta))
        except ConfigError as exc:
            ctx.problems.append(f"step {step.index}: {terms}-term fit failed ({exc})")
    if not fits:
        return []
    t0 = fits[0].t0
    hold = t >= t0
    g = modulus_history(force[hold], depth, radius)
    th = t[hold] - t0
    png = f"hold_{step.index:02d}.png"
    plot_hold_fits(ctx.out / png, th, g, fits,
                   f"{step.name}: G(t) = F / (K delta^1.5), R {radius * 1e3:.3f} mm, "
                   f"delta {depth * 1e3:.3f} mm")
    rows: list[dict[str, object]] = []
    for fit in fits:
        for name, value in [("G_e", fit.g_e), *[(n, v) for k, r in enumerate(fit.relax, 1)
                                                 for n, v in ((f"G_{k}", r.g),
                                                              (f"tau_{k}", r.tau))]]:
            rows.append({"terms": len(fit.relax), "parameter": name, "value": value,
                         "stderr": fit.stderr.get(name, math.nan), "rmse_Pa": fit.rmse})
    table = Table("Prony fits of G(t) over the hold (SI: Pa, s)",
                  (Column("terms", "terms"), Column("parameter", "parameter"),
                   Column("value", "value"), Column("stderr", "std. error", digits=3),
                   Column("rmse_Pa", "rmse (Pa)", digits=3)), rows,
                  f"hold_{step.index:02d}_fits.csv")
    res_rows = [{"t_s": float(a), "G_Pa": float(b), "residual_1_Pa": float(b - fits[0].model(a)),
                 "residual_2_Pa": float(b - fits[-1].model(a))}
                for a, b in zip(*_bin_means(th, g, 300), strict=True)]
    res_table = Table("G(t) and residuals, 300 equal-count bin means",
                      (Column("t_s", "t (s)"), Column("G_Pa", "G (Pa)"),
                       Column("residual_1_Pa", "1-term residual (Pa)", digits=3),
                       Column("residual_2_Pa", "2-term residual (Pa)", digits=3)),
                      res_rows, f"hold_{step.index:02d}_residuals.csv")
    ctx.sections.append(Section(
        f"Compression: {step.name} (step {step.index})",
        [f"Hold of {recorded:.0f} s, {int(np.count_nonzero(hold))} samples; sphere radius "
         f"{radius * 1e3:.3f} mm, hold overlap {depth * 1e3:.4f} mm. The amplitudes are those "
         "at the hold start; the ramp-corrected material amplitudes are in run.json fits."],
        [(png, "Back-calculated modulus with the 1- and 2-term fits; residuals below.")],
        [table, res_table]))
    ctx.summary.append(f"Hold, step {step.index} ({step.name}): {recorded:.0f} s, "
                       f"{int(np.count_nonzero(hold))} samples, delta {depth * 1e3:.3f} mm")
    for fit in fits:
        text = "; ".join(f"G_{k} {r.g:.0f} +- {fit.stderr.get(f'G_{k}', math.nan):.2g} Pa, "
                          f"tau_{k} {r.tau:.0f} +- {fit.stderr.get(f'tau_{k}', math.nan):.2g} s"
                          for k, r in enumerate(fit.relax, 1))
        ctx.summary.append(f"  {len(fit.relax)}-term: G_e {fit.g_e:.0f} +- "
                           f"{fit.stderr.get('G_e', math.nan):.2g} Pa; {text}; "
                           f"rmse {fit.rmse:.3g} Pa")
    return fits


def _bin_means(t: FloatArray, y: FloatArray, n: int) -> tuple[FloatArray, FloatArray]:
    if t.size <= n:
        return t, y
    edges = np.linspace(0, t.size, n + 1).astype(int)
    counts = np.diff(edges)
    return np.add.reduceat(t, edges[:-1]) / counts, np.add.reduceat(y, edges[:-1]) / counts


# -- shear -----------------------------------------------------------------------------------

_PASS_COLUMNS = (
    Column("pass", "pass"), Column("direction", "dir"), Column("speed_m_s", "v (m/s)", digits=3),
    Column("overlap_m", "overlap (mm)", 1e3), Column("l_c_m", "l_c (mm)", 1e3),
    Column("l_g_m", "l_g (mm)", 1e3), Column("l_c_over_l_g", "l_c/l_g"),
    Column("f_h_peak_N", "F_h peak (mN)", 1e3), Column("f_h_trough_N", "F_h trough (mN)", 1e3),
    Column("f_v_peak_N", "F_v peak (mN)", 1e3),
    Column("zero_offset_m", "zero offset (um)", 1e6, 3), Column("mu", "mu", digits=3),
    Column("contact_start_m", "contact start (mm)", 1e3, 6),
    Column("contact_end_m", "contact end (mm)", 1e3, 6),
)
_LEVEL_COLUMNS = (
    Column("overlap_m", "overlap (mm)", 1e3), Column("speed_m_s", "v (m/s)", digits=3),
    Column("l_g_m", "l_g (mm)", 1e3), Column("l_g_geom_m", "l_g geometric, fit (mm)", 1e3),
    Column("l_c_C_m", "l_c C (mm)", 1e3), Column("l_c_AC_m", "l_c AC (mm)", 1e3),
    Column("l_c_over_l_g", "mean l_c/l_g"), Column("mu_C", "mu C", digits=3),
    Column("mu_AC", "mu AC", digits=3), Column("mu", "mu (C+AC)/2", digits=3),
    Column("zero_offset_m", "zero offset (um)", 1e6, 3),
)


def _search_geometry(steps: list[StepData], ladder: StepData) -> tuple[float, float, str]:
    """Touch gap (m) and lower-sphere angle (rad) for the fit's start, and where from."""
    touch = float(ladder.params.get("touch_gap") or math.nan)  # None: from the search
    angle = float(ladder.params.get("centre_angle") or math.nan)
    source = "the ladder's parameters"
    for s in steps:
        if s.kind == "shear_contact_search" and s.index < ladder.index:
            if not math.isfinite(touch):
                touch, source = float(s.results.get("touch_gap_m", math.nan)), "the contact search"
            if not math.isfinite(angle):
                angle = float(s.results.get("lower_sphere_angle_rad", math.nan))
    if not (math.isfinite(touch) and math.isfinite(angle)):
        touch = float(ladder.results.get("touch_gap_m", touch))
        angle = float(ladder.results.get("centre_angle_rad", angle))
    return touch, angle, source


def _ladder(
    ctx: _Context, steps: list[StepData], step: StepData, arm: float
) -> tuple[LadderAnalysis, ModelFit | None] | None:
    travel = step.params.get("travel")
    try:
        analysis, passes = analyse_ladder(step.columns, arm,
                                          None if travel is None else float(travel))
    except ConfigError as exc:
        ctx.problems.append(f"step {step.index} ({step.name}): {exc}")
        return None
    ctx.problems.extend(f"step {step.index}: {p}" for p in analysis.problems)
    if not analysis.results:
        ctx.problems.append(f"step {step.index} ({step.name}): no complete pass to analyse")
        return None
    fit = _model_fit(ctx, steps, step, analysis) if ctx.fit_model else None
    levels = analysis.levels()
    for row in levels:
        row["l_g_geom_m"] = _l_g_geom(ctx.setup.s, fit, passes, analysis.results, row) \
            if fit else math.nan
    section = Section(f"Shear: {step.name} (step {step.index})", [
        f"{len(analysis.results)} passes analysed; arm {arm * 1e3:g} mm. l_c: first rise to "
        "return to baseline (5 sigma of the pre-contact noise, F_h or F_v); l_g: between the "
        "first-contact points of the clockwise and anticlockwise passes at the same overlap and "
        "speed; mu: F_h/F_v at the centre of l_g (second-degree polynomials over 20 samples "
        "each side), averaged over C and AC, which cancels an error of the centre to first "
        "order. Definitions: docs/decisions/0030-analysis-definitions.md."])
    _shear_figures(ctx, steps, step, analysis, passes, levels, fit, section)
    section.tables += [
        Table("Per (overlap, speed)", _LEVEL_COLUMNS, levels,
              f"ladder_{step.index:02d}_levels.csv"),
        Table("Per pass", _PASS_COLUMNS, [r.row() for r in analysis.results],
              f"ladder_{step.index:02d}_passes.csv"),
    ]
    if fit is not None:
        section.tables.insert(0, Table(
            "Model fit to all passes (SI; 95 % confidence intervals)",
            (Column("parameter", "parameter"), Column("value", "value", digits=6),
             Column("stderr", "std. error", digits=3), Column("ci95_lo", "95 % low", digits=6),
             Column("ci95_hi", "95 % high", digits=6), Column("unit", "unit")),
            fit.rows(), f"ladder_{step.index:02d}_model_fit.csv"))
    ctx.sections.append(section)
    _shear_summary(ctx, step, analysis, levels, fit)
    return analysis, fit


def _l_g_geom(s: float, fit: ModelFit, passes: list[RecordedPass], results: list[PassResult],
              row: Mapping[str, float]) -> float:
    """2 sqrt(S^2 - h^2) with the fitted touch gap and the pass's recorded gap."""
    gaps = [float(np.median(p.gap[p.gap.size // 4: 3 * p.gap.size // 4]))
            for p, r in zip(passes, results, strict=True)
            if round(r.overlap, 9) == row["overlap_m"] and r.speed == row["speed_m_s"]]
    if not gaps:
        return math.nan
    h = s - (fit.touch_gap - float(np.mean(gaps)))
    return 2.0 * math.sqrt(max(s * s - h * h, 0.0))


def _history(steps: list[StepData], step: StepData) -> list[dict[str, FloatArray]]:
    """The shear steps up to and including ``step``: the motion the contact has seen. Only
    ``step``'s passes keep their labels (they are the ones fitted)."""
    out = []
    for s in steps:
        if s.index > step.index or s.kind not in ("shear_contact_search", "speed_ladder"):
            continue
        if not {"t_s", "angle_rad", "gap_m", "torque_Nm", "normal_force_N", "pass",
                "direction"} <= set(s.columns):
            continue
        out.append(s.columns if s.index == step.index else _unlabelled(s.columns))
    return out


def _model_fit(ctx: _Context, steps: list[StepData], step: StepData,
               analysis: LadderAnalysis) -> ModelFit | None:
    touch, angle, source = _search_geometry(steps, step)
    if not (math.isfinite(touch) and math.isfinite(angle)):
        ctx.problems.append(f"step {step.index}: model fit skipped: no touch gap or lower-sphere "
                            "angle (no contact search result and none in the ladder's parameters)")
        return None
    try:
        fit = fit_ladder(Trajectory.from_steps(_history(steps, step)), analysis.results,
                         ctx.setup, touch, angle)
    except (ConfigError, ValueError, np.linalg.LinAlgError) as exc:
        ctx.problems.append(f"step {step.index}: model fit failed ({exc})")
        return None
    fit.extra["start_from"] = source
    return fit


def _shear_figures(ctx: _Context, steps: list[StepData], step: StepData, analysis: LadderAnalysis,
                   passes: list[RecordedPass], levels: list[dict[str, float]],
                   fit: ModelFit | None, section: Section) -> None:
    arm = ctx.setup.arm
    results = analysis.results
    forces = {p.index: pass_forces(p, arm) for p in passes}
    by_index = {p.index: p for p in passes}
    prefix = f"ladder_{step.index:02d}"
    overlaps = sorted({round(r.overlap, 9) for r in results})
    speeds = sorted({r.speed for r in results})
    deepest, slowest = overlaps[-1], speeds[0]

    def curve(r: PassResult, label: str, marks: bool = True) -> PassCurve:
        f = forces[r.index]
        m = f.moving
        return PassCurve(label, f.theta[m], f.f_h[m], f.f_v[m],
                         (r.contact_start, r.contact_end) if marks else ())

    pair = [r for r in results if round(r.overlap, 9) == deepest and r.speed == slowest]
    if pair:
        centre = pair[0].centre if math.isfinite(pair[0].centre) else 0.0
        curves = [curve(r, f"{'C' if r.direction > 0 else 'AC'}: l_c {r.l_c * 1e3:.3f} mm")
                  for r in pair]
        name = f"{prefix}_C_AC.png"
        plot_pass_curves(ctx.out / name, curves, f"overlap {deepest * 1e3:.2f} mm, "
                         f"{slowest:.3g} m/s: l_g {pair[0].l_g * 1e3:.3f} mm", centre)
        section.figures.append((name, "F_h and F_v of the clockwise and anticlockwise passes; "
                                "dotted: contact start and end of each (l_c)."))
    for key, fixed, label, name, caption in (
        ("speed", deepest, "overlap", f"{prefix}_speeds.png",
         "Clockwise passes at the deepest overlap, one per speed."),
        ("overlap", slowest, "speed", f"{prefix}_overlaps.png",
         "Clockwise passes at the slowest speed, one per overlap."),
    ):
        chosen = [r for r in results if r.direction > 0 and (
            (key == "speed" and round(r.overlap, 9) == fixed) or
            (key == "overlap" and r.speed == fixed))]
        if not chosen:
            continue
        centre = float(np.nanmedian([r.centre for r in chosen])) \
            if any(math.isfinite(r.centre) for r in chosen) else 0.0
        curves = [curve(r, f"{r.speed:.3g} m/s" if key == "speed" else
                        f"{r.overlap * 1e3:.2f} mm", marks=False) for r in chosen]
        title = f"{label} {fixed * 1e3:.2f} mm" if key == "speed" else f"{label} {fixed:.3g} m/s"
        plot_pass_curves(ctx.out / name, curves, f"clockwise, {title}", centre)
        section.figures.append((name, caption))
    def by_overlap(key: str) -> dict[str, tuple[FloatArray, FloatArray]]:
        return {f"{o * 1e3:.2f} mm": (
            np.array([r["speed_m_s"] for r in levels if r["overlap_m"] == o]),
            np.array([r[key] for r in levels if r["overlap_m"] == o])) for o in overlaps}

    ratio = by_overlap("l_c_over_l_g")
    plot_vs_speed(ctx.out / f"{prefix}_lc_lg.png", ratio, "l_c / l_g",
                  "deformed over geometric contact length", 1.0, "l_c = l_g")
    section.figures.append((f"{prefix}_lc_lg.png", "l_c/l_g (mean of C and AC) against speed, "
                            "one line per overlap."))
    mus = by_overlap("mu")
    plot_vs_speed(ctx.out / f"{prefix}_mu.png", mus, "mu = F_h / F_v at the centre of l_g",
                  "friction coefficient", fit.mu if fit else None,
                  f"model fit mu {fit.mu:.4g}" if fit else "")
    section.figures.append((f"{prefix}_mu.png", "Friction coefficient against speed, one line "
                            "per overlap; dashed: the model fit."))
    if fit is None:
        return
    # The model over this ladder with its full history (the trajectory the fit used).
    full = Trajectory.from_steps(_history(steps, step))
    f_h_model, f_v_model = model_forces(full, fit, ctx.setup)
    order = sorted(results, key=lambda r: (round(r.overlap, 9), r.speed, -r.direction))
    panels_h, panels_v = [], []
    for r in order:
        p = by_index[r.index]
        f = forces[r.index]
        where = np.flatnonzero(full.pass_index == p.index)
        lo, hi = sorted((r.contact_start, r.contact_end))
        pad = 0.15 * (hi - lo)
        win = f.moving & (f.theta > lo - pad) & (f.theta < hi + pad)
        title = f"{r.overlap * 1e3:.2f} mm {r.speed:.2g} {'C' if r.direction > 0 else 'AC'}"
        panels_h.append(FitPanel(title, f.theta[win], f.f_h[win], f_h_model[where][win]))
        panels_v.append(FitPanel(title, f.theta[win], f.f_v[win], f_v_model[where][win]))
    cols = 2 * len(speeds)
    for kind, panels, ylabel in (("fh", panels_h, "F_h (mN)"), ("fv", panels_v, "F_v (mN)")):
        name = f"{prefix}_model_{kind}.png"
        plot_fit_grid(ctx.out / name, panels, cols, ylabel,
                      f"{ylabel[:3]}: data (grey) and the fitted model (red)")
        section.figures.append((name, f"{ylabel[:3]} of every pass against the model fitted to "
                                "all passes at once."))


def _unlabelled(columns: Mapping[str, FloatArray]) -> dict[str, FloatArray]:
    out = dict(columns)
    out["pass"] = np.full(out["t_s"].size, -1.0)
    return out


def _shear_summary(ctx: _Context, step: StepData, analysis: LadderAnalysis,
                   levels: list[dict[str, float]], fit: ModelFit | None) -> None:
    speeds = sorted({r["speed_m_s"] for r in levels})
    overlaps = sorted({r["overlap_m"] for r in levels})
    lines = ctx.summary
    lines.append(f"Shear ladder, step {step.index} ({step.name}): {len(analysis.results)} "
                 f"passes, {len(overlaps)} overlaps x {len(speeds)} speeds")
    head = "".join(f"{v:>11.3g}" for v in speeds)
    lines.append(f"  {'l_c/l_g':<14s}{head}   | mu (C+AC)/2 at the same speeds")
    for o in overlaps:
        row = {r["speed_m_s"]: r for r in levels if r["overlap_m"] == o}
        ratio = "".join(f"{row[v]['l_c_over_l_g']:>11.4f}" if v in row else f"{'-':>11s}"
                        for v in speeds)
        mu = "".join(f"{row[v]['mu']:>9.4f}" if v in row else f"{'-':>9s}" for v in speeds)
        lgs = [r["l_g_m"] for r in row.values() if math.isfinite(r["l_g_m"])]
        lg = f"{np.mean(lgs) * 1e3:5.2f}" if lgs else f"{'-':>5s}"
        lines.append(f"  {o * 1e3:.2f} mm l_g {lg}{ratio}   |{mu}")
    if fit is not None:
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
        lines.append(f"  model fit to all passes ({fit.n_points} points per force, "
                     f"{fit.seconds:.1f} s), 95 % CI:")
        for i in range(0, len(parts), 2):
            lines.append("    " + "; ".join(parts[i:i + 2]))
        lines.append(f"    rms residual F_h {fit.rms_h * 1e3:.4f} mN (noise "
                     f"{fit.noise_h * 1e3:.4f}), F_v {fit.rms_v * 1e3:.4f} mN (noise "
                     f"{fit.noise_v * 1e3:.4f})")


# -- entry point -----------------------------------------------------------------------------

def analyze_run(
    run_dir: str | Path,
    out_dir: str | Path | None = None,
    *,
    r1: float = paper.R1_SHEAR,
    r2: float = paper.R2_SHEAR,
    terms: int = 1,
    fit_model: bool = True,
    fit_geometry: bool = True,
) -> AnalysisResult:
    """Analyse every complete part of a run directory and write the report.

    ``out_dir`` defaults to ``RUN_DIR/analysis``. ``r1``, ``r2`` (m) are the shear rig's
    sphere radii (not stored with a run); ``terms`` is the number of relaxation terms of the
    shear model fit. Raises ConfigError when there is nothing at all to analyse.
    """
    run = RunDirectory(run_dir)
    meta = run.read_metadata()
    out = Path(out_dir) if out_dir is not None else run.path / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    problems: list[str] = []
    steps = load_steps(run, meta, problems)
    kind = str((meta.get("protocol") or {}).get("protocol", {}).get("rig", "?"))
    arm = _arm(meta, problems) if any(s.kind == "speed_ladder" for s in steps) else paper.ARM
    ctx = _Context(run, out, meta, problems, [], [],
                   FitSetup(r1, r2, arm, terms=terms, fit_geometry=fit_geometry), fit_model)
    result = AnalysisResult(run.path, out, out / "report.html", "", problems)
    for step in steps:
        if step.kind == "ramp_hold":
            fits = _hold(ctx, step)
            if fits:
                result.hold_fits[step.index] = fits
        elif step.kind == "speed_ladder":
            done = _ladder(ctx, steps, step, arm)
            if done is not None:
                result.ladders[step.index] = done[0]
                if done[1] is not None:
                    result.model_fits[step.index] = done[1]
    if not (result.hold_fits or result.ladders):
        raise ConfigError("run", str(run.path), "holds no analysable hold or ladder data"
                          + (f" ({problems[0]})" if problems else ""))
    status = meta.get("status", "?")
    header = [f"gelrig analyze {run.path}  ({kind} rig, run {status})"]
    if problems:
        header.append(f"INCOMPLETE: {len(problems)} problem(s):")
        header += [f"  - {p}" for p in problems[:8]]
        if len(problems) > 8:
            header.append(f"  ... and {len(problems) - 8} more (see the report)")
    summary = "\n".join([*header, *ctx.summary])
    page = write_report(out, f"gelrig analysis: {run.path.name}", summary, ctx.sections,
                        problems)
    result.summary = summary + f"\nreport: {page.resolve()}"
    result.report_path = page
    return result

