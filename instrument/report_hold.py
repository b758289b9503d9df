"""The report's part for a ramp-and-hold step: figure, tables, summary lines and problems.

Formatting only: every number comes from a :class:`instrument.hold_analysis.HoldAnalysis`.
"""

from __future__ import annotations

import math
from pathlib import Path

from instrument.analysis import RelaxationFit
from instrument.hold_analysis import HoldAnalysis
from instrument.report import Column, Section, Table
from instrument.report_plots import plot_hold_fits

#: Bin means in the table of G(t) and residuals.
RESIDUAL_BINS = 300

_FIT_COLUMNS = (
    Column("terms", "terms"), Column("parameter", "parameter"), Column("value", "value"),
    Column("stderr", "std. error", digits=3), Column("rmse_Pa", "rmse (Pa)", digits=3),
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


def fit_rows(fits: tuple[RelaxationFit, ...]) -> list[dict[str, object]]:
    """One row per fitted parameter of every fit (SI), with its standard error."""
    rows: list[dict[str, object]] = []
    for fit in fits:
        params = [("G_e", fit.g_e)]
        for k, term in enumerate(fit.relax, 1):
            params += [(f"G_{k}", term.g), (f"tau_{k}", term.tau)]
        rows += [{"terms": len(fit.relax), "parameter": p, "value": v,
                  "stderr": fit.stderr.get(p, math.nan), "rmse_Pa": fit.rmse}
                 for p, v in params]
    return rows


def residual_rows(hold: HoldAnalysis) -> list[dict[str, object]]:
    """G(t) bin means with the first and the last fit's residual (SI)."""
    res = hold.residuals(RESIDUAL_BINS)
    return [{"t_s": float(t), "G_Pa": float(g), "residual_1_Pa": float(r1),
             "residual_2_Pa": float(r2)}
            for t, g, r1, r2 in zip(res.t, res.g, res.residuals[0], res.residuals[-1],
                                    strict=True)]


def hold_summary(hold: HoldAnalysis, index: int, name: str) -> list[str]:
    """The stdout summary's lines for this hold: its extent, then one line per fit."""
    lines = [f"Hold, step {index} ({name}): {hold.duration:.0f} s, {hold.samples} samples, "
             f"delta {hold.depth * 1e3:.3f} mm"]
    for fit in hold.fits:
        err = fit.stderr
        text = "; ".join(f"G_{k} {r.g:.0f} +- {err.get(f'G_{k}', math.nan):.2g} Pa, "
                         f"tau_{k} {r.tau:.0f} +- {err.get(f'tau_{k}', math.nan):.2g} s"
                         for k, r in enumerate(fit.relax, 1))
        lines.append(f"  {len(fit.relax)}-term: G_e {fit.g_e:.0f} +- "
                     f"{err.get('G_e', math.nan):.2g} Pa; {text}; rmse {fit.rmse:.3g} Pa")
    return lines


def hold_section(hold: HoldAnalysis, index: int, name: str, out: Path) -> Section:
    """The report section of a fitted hold; its figure is written to ``out``."""
    radius, depth = hold.radius, hold.depth
    png = f"hold_{index:02d}.png"
    plot_hold_fits(out / png, hold.t, hold.g, hold.fits,
                   f"{name}: G(t) = F / (K delta^1.5), R {radius * 1e3:.3f} mm, "
                   f"delta {depth * 1e3:.3f} mm")
    return Section(
        f"Compression: {name} (step {index})",
        [f"Hold of {hold.duration:.0f} s, {hold.samples} samples; sphere radius "
         f"{radius * 1e3:.3f} mm, hold overlap {depth * 1e3:.4f} mm. The amplitudes are those "
         "at the hold start; the ramp-corrected material amplitudes are in run.json fits."],
        [(png, "Back-calculated modulus with the 1- and 2-term fits; residuals below.")],
        [Table("Prony fits of G(t) over the hold (SI: Pa, s)", _FIT_COLUMNS,
               fit_rows(hold.fits), f"hold_{index:02d}_fits.csv"),
         Table(f"G(t) and residuals, {RESIDUAL_BINS} equal-count bin means", _RESIDUAL_COLUMNS,
               residual_rows(hold), f"hold_{index:02d}_residuals.csv")])
