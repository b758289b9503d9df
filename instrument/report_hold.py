"""The report's part for a ramp-and-hold step: figure, tables, summary lines and problems.

Formatting only: every number comes from a :class:`instrument.hold_analysis.HoldAnalysis`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

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


_LIVE_COLUMNS = (
    Column("elapsed_s", "hold time (s)"), Column("tau_1_s", "tau_1 (s)"),
    Column("tau_1_rel", "tau_1 rel. s.e.", digits=3),
    Column("tau_1_forecast", "forecast at end", digits=3),
    Column("tau_2_s", "tau_2 (s)"), Column("tau_2_rel", "tau_2 rel. s.e.", digits=3),
    Column("resolved", "terms resolved"),
)


def _num(value: object) -> float:
    return float(value) if isinstance(value, int | float) else math.nan


def live_rows(live_fits: list[dict[str, Any]]) -> list[dict[str, object]]:
    """One row per refit of the live fit during the hold (SI; NaN where absent)."""
    rows: list[dict[str, object]] = []
    for fit in live_fits:
        relax = fit.get("relax") or []
        rel, fc = fit.get("relative") or {}, fit.get("forecast") or {}
        rows.append({
            "elapsed_s": _num(fit.get("elapsed_s")),
            "tau_1_s": _num(relax[0]["tau"]) if relax else math.nan,
            "tau_1_rel": _num(rel.get("tau_1")), "tau_1_forecast": _num(fc.get("tau_1")),
            "tau_2_s": _num(relax[1]["tau"]) if len(relax) > 1 else math.nan,
            "tau_2_rel": _num(rel.get("tau_2")),
            "resolved": _num(fit.get("terms_resolved"))})
    return rows


def hold_end_line(results: Mapping[str, Any], params: Mapping[str, Any]) -> str:
    """How the hold ended (adaptive or not) and what the last live refit said; "" when the
    step has no live fit (a run recorded before issue 16)."""
    live = results.get("live_fits") or []
    end = results.get("hold_end", "")
    held = _num(results.get("held_s"))
    asked = _num(params.get("hold"))
    until = _num(params.get("until")) * 100
    terms = _num(params.get("until_terms"))
    terms = int(terms) if math.isfinite(terms) else 1
    why = {"target": f"adaptive hold ended on its target (every tau to {until:g} %, "
                     f"{terms} term(s) resolved) after {held:.0f} s of at most {asked:g} s",
           "maximum": f"adaptive hold reached its maximum {asked:g} s without meeting its "
                      f"target ({until:g} %)",
           "requested": f"hold ended on request after {held:.0f} s of {asked:g} s",
           "planned": f"hold of {held:.0f} s as planned"}.get(str(end), "")
    if not live:
        return why
    last = live[-1]
    relax = last.get("relax") or []
    rel = _num((last.get("relative") or {}).get("tau_1"))
    tau = (f"; last refit at {_num(last.get('elapsed_s')):.0f} s: tau_1 "
           f"{_num(relax[0]['tau']):.0f} s +- {rel * 100:.2g} %, "
           f"{last.get('terms_resolved', 0)} term(s) resolved") if relax else ""
    fits = f"live fit: {len(live)} refits{tau}"
    return f"{why}; {fits}" if why else fits


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


def hold_summary(hold: HoldAnalysis, index: int, name: str,
                 results: Mapping[str, Any] | None = None,
                 params: Mapping[str, Any] | None = None) -> list[str]:
    """The stdout summary's lines for this hold: its extent, how it ended and its live fit
    (from the step's ``results`` and ``params`` in run.json), then one line per fit."""
    delta = hold.overlap.held if hold.overlap is not None else hold.depth
    lines = [f"Hold, step {index} ({name}): {hold.duration:.0f} s, {hold.samples} samples, "
             f"delta {delta * 1e3:.3f} mm"]
    if hold.overlap is not None:
        lines.append(f"  {overlap_line(hold)}")
    end = hold_end_line(results or {}, params or {})
    if end:
        lines.append(f"  {end}")
    lines += [f"  {fit_line(fit)}" for fit in hold.fits]
    return lines


def hold_section(hold: HoldAnalysis, index: int, name: str, out: Path,
                 results: Mapping[str, Any] | None = None,
                 params: Mapping[str, Any] | None = None) -> Section:
    """The report section of a fitted hold; its figure is written to ``out``. With the step's
    ``results`` (run.json), also how the hold ended and the live fit's history."""
    radius = hold.radius
    depth = hold.overlap.held if hold.overlap is not None else hold.depth
    png = f"hold_{index:02d}.png"
    plot_hold_fits(out / png, hold.t, hold.g, hold.fits,
                   f"{name}: G(t) = F / (K delta^1.5), R {radius * 1e3:.3f} mm, "
                   f"delta {depth * 1e3:.3f} mm")
    notes = [f"{len(f.relax)}-term fit: {f.not_resolved}." for f in hold.fits if f.not_resolved]
    end = hold_end_line(results or {}, params or {})
    if end:
        notes.append(end[0].upper() + end[1:] + ".")
    live = list((results or {}).get("live_fits") or [])
    tables = [Table("Live fit during the hold (each refit; relative standard errors now and "
                    "forecast at the planned end)", _LIVE_COLUMNS, live_rows(live),
                    f"hold_{index:02d}_live_fit.csv")] if live else []
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
               residual_rows(hold), f"hold_{index:02d}_residuals.csv"), *tables])
