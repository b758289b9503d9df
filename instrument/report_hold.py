"""The report's part for a ramp-and-hold step: figure, tables, summary lines and problems.

Formatting only: every number comes from a :class:`instrument.hold_analysis.HoldAnalysis`.
"""

from __future__ import annotations

import math
from pathlib import Path

from instrument.analysis import UNDETERMINED, RelaxationFit, format_stderr
from instrument.hold_analysis import HoldAnalysis
from instrument.report import Column, Section, Table
from instrument.report_plots import plot_hold_fits

#: Bin means in the table of G(t) and residuals.
RESIDUAL_BINS = 300

_FIT_COLUMNS = (
    Column("terms", "terms"), Column("parameter", "parameter"), Column("value", "value"),
    Column("stderr", "std. error", digits=3), Column("rmse_Pa", "rmse (Pa)", digits=3),
    Column("resolved", "terms resolved"),
)
_RESIDUAL_COLUMNS = (
    Column("t_s", "t (s)"), Column("G_Pa", "G (Pa)"),
    Column("residual_1_Pa", "1-term residual (Pa)", digits=3),
    Column("residual_2_Pa", "2-term residual (Pa)", digits=3),
)


def hold_problems(hold: HoldAnalysis, index: int, name: str) -> list[str]:
    """What the analysis of this hold could not do as planned, one line each."""
    out = []
    if hold.truncated:
        out.append(f"step {index} ({name}): hold recorded for {hold.duration:.0f} s of the "
                   f"planned {hold.planned:.0f} s; fitting that")
    out += [f"step {index}: {terms}-term fit failed ({why})"
            for terms, why in hold.fit_errors.items()]
    return out


def _stderr_cell(value: float) -> float | str:
    return value if format_stderr(value) != UNDETERMINED else UNDETERMINED


def fit_rows(fits: tuple[RelaxationFit, ...]) -> list[dict[str, object]]:
    """One row per fitted parameter of every fit (SI), with its standard error (``undetermined``
    where the covariance does not give it) and how many of the fit's terms the data resolve."""
    rows: list[dict[str, object]] = []
    for fit in fits:
        params = [("G_e", fit.g_e)]
        for k, term in enumerate(fit.relax, 1):
            params += [(f"G_{k}", term.g), (f"tau_{k}", term.tau)]
        rows += [{"terms": len(fit.relax), "parameter": p, "value": v,
                  "stderr": _stderr_cell(fit.stderr.get(p, math.nan)), "rmse_Pa": fit.rmse,
                  "resolved": fit.terms_resolved if fit.terms_resolved >= 0 else math.nan}
                 for p, v in params]
    return rows


def fit_line(fit: RelaxationFit) -> str:
    """One fit in one line: parameters with standard errors (``undetermined`` where the
    covariance does not give them), rmse, and whether its terms are resolved."""
    err = fit.stderr
    text = "; ".join(f"G_{k} {r.g:.0f} +- {format_stderr(err.get(f'G_{k}', math.nan))} Pa, "
                     f"tau_{k} {r.tau:.0f} +- {format_stderr(err.get(f'tau_{k}', math.nan))} s"
                     for k, r in enumerate(fit.relax, 1))
    line = (f"{len(fit.relax)}-term: G_e {fit.g_e:.0f} +- "
            f"{format_stderr(err.get('G_e', math.nan))} Pa; {text}; rmse {fit.rmse:.3g} Pa")
    return line + (f" -- {fit.not_resolved}" if fit.not_resolved else "")


def overlap_line(hold: HoldAnalysis) -> str:
    """Where first touch was and which overlap the fits used."""
    m = hold.overlap
    if m is None:
        return f"overlap: the planned {hold.depth * 1e3:.4f} mm (no plate positions)"
    how = ("refitted on the ramp" if m.touch is not None
           else f"from the contact search ({m.why})")
    return (f"first touch {m.first_touch * 1e3:.4f} mm ({how}; contact search "
            f"{m.recorded_touch * 1e3:.4f} mm); measured overlap {m.held * 1e3:.4f} mm "
            f"(planned {hold.depth * 1e3:.4f} mm, load-cell compliance "
            f"{m.compliance * 1e6:g} um/N)")


def residual_rows(hold: HoldAnalysis) -> list[dict[str, object]]:
    """G(t) bin means with the first and the last fit's residual (SI)."""
    res = hold.residuals(RESIDUAL_BINS)
    return [{"t_s": float(t), "G_Pa": float(g), "residual_1_Pa": float(r1),
             "residual_2_Pa": float(r2)}
            for t, g, r1, r2 in zip(res.t, res.g, res.residuals[0], res.residuals[-1],
                                    strict=True)]


def hold_summary(hold: HoldAnalysis, index: int, name: str) -> list[str]:
    """The stdout summary's lines for this hold: its extent, then one line per fit."""
    delta = hold.overlap.held if hold.overlap is not None else hold.depth
    lines = [f"Hold, step {index} ({name}): {hold.duration:.0f} s, {hold.samples} samples, "
             f"delta {delta * 1e3:.3f} mm"]
    if hold.overlap is not None:
        lines.append(f"  {overlap_line(hold)}")
    lines += [f"  {fit_line(fit)}" for fit in hold.fits]
    return lines


def hold_section(hold: HoldAnalysis, index: int, name: str, out: Path) -> Section:
    """The report section of a fitted hold; its figure is written to ``out``."""
    radius = hold.radius
    depth = hold.overlap.held if hold.overlap is not None else hold.depth
    png = f"hold_{index:02d}.png"
    plot_hold_fits(out / png, hold.t, hold.g, hold.fits,
                   f"{name}: G(t) = F / (K delta^1.5), R {radius * 1e3:.3f} mm, "
                   f"delta {depth * 1e3:.3f} mm")
    notes = [f"{len(f.relax)}-term fit: {f.not_resolved}." for f in hold.fits if f.not_resolved]
    return Section(
        f"Compression: {name} (step {index})",
        [f"Hold of {hold.duration:.0f} s, {hold.samples} samples; sphere radius "
         f"{radius * 1e3:.3f} mm; {overlap_line(hold)}. The amplitudes are those "
         "at the hold start; the ramp-corrected material amplitudes are in run.json fits. "
         "Terms are ordered longest time constant first; a term is resolved when it lowers "
         "the BIC by at least 10, every amplitude and time constant has a relative standard "
         "error below 0.25 and the time constants are at least 2x apart (docs/decisions/0160).",
         *notes],
        [(png, "Back-calculated modulus with the 1- and 2-term fits; residuals below.")],
        [Table("Prony fits of G(t) over the hold (SI: Pa, s)", _FIT_COLUMNS,
               fit_rows(hold.fits), f"hold_{index:02d}_fits.csv"),
         Table(f"G(t) and residuals, {RESIDUAL_BINS} equal-count bin means", _RESIDUAL_COLUMNS,
               residual_rows(hold), f"hold_{index:02d}_residuals.csv")])
