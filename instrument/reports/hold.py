"""The report's part for a ramp-and-hold step: figure, tables, summary lines and problems.

Formatting only: every number comes from a
:class:`gelrig.instrument.analysis.hold_analysis.HoldAnalysis`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gelrig.instrument.analysis.hold_analysis import HoldAnalysis
from gelrig.instrument.analysis.relaxation import (
    UNDETERMINED,
    RelaxationFit,
    format_stderr,
    shown_amplitude,
)
from gelrig.instrument.physics.material import RelaxationTerm
from gelrig.instrument.reports.document import Column, Section, Table
from gelrig.instrument.reports.figures import plot_hold_fits

#: Bin means in the table of G(t) and residuals.
RESIDUAL_BINS = 300

_FIT_COLUMNS = (
    Column("terms", "terms"), Column("parameter", "parameter"), Column("value", "value"),
    Column("stderr", "std. error", digits=3), Column("rmse_Pa", "rmse (Pa)", digits=3),
    Column("resolved", "resolved"), Column("reason", "not resolved because"),
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
    Column("resolved", "resolved"), Column("reason", "not resolved because"),
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
    where the covariance does not give it), ``resolved`` (true/false: the data resolve every
    term of that fit) and the ``reason`` when not; an unresolved fit's rows carry no values."""
    rows: list[dict[str, object]] = []
    for fit in fits:
        params = [("G_e", fit.g_e)]
        for k, term in enumerate(fit.relax, 1):
            params += [(f"G_{k}", term.g), (f"tau_{k}", term.tau)]
        ok = fit.is_resolved
        rows += [{"terms": len(fit.relax), "parameter": p, "value": v if ok else None,
                  "stderr": _stderr_cell(fit.stderr.get(p, math.nan)) if ok else None,
                  "rmse_Pa": fit.rmse if ok else None, "resolved": ok, "reason": fit.reason}
                 for p, v in params]
    return rows


def fit_line(fit: RelaxationFit) -> str:
    """One fit in one line: parameters with standard errors (``undetermined`` where the
    covariance does not give them) and rmse; a fit whose terms the data do not all resolve
    is ``N-term: not resolved: <reason>``, without values."""
    if not fit.is_resolved:
        return f"{len(fit.relax)}-term: not resolved: {fit.reason}"
    err = fit.stderr

    def term(k: int, r: RelaxationTerm) -> str:
        g, note = shown_amplitude(fit.extra, k, r.g)
        se = err.get(f"G_{k}", math.nan) * (g / r.g if r.g else 1.0)
        return (f"G_{k} {g:.0f} +- {format_stderr(se)} Pa{note}, "
                f"tau_{k} {r.tau:.0f} +- {format_stderr(err.get(f'tau_{k}', math.nan))} s")

    text = "; ".join(term(k, r) for k, r in enumerate(fit.relax, 1))
    line = (f"{len(fit.relax)}-term: G_e {fit.g_e:.0f} +- "
            f"{format_stderr(err.get('G_e', math.nan))} Pa; {text}; rmse {fit.rmse:.3g} Pa")
    return line + (f" -- {fit.not_resolved}" if fit.not_resolved else "")


#: The held overlap should exceed first touch's standard error (or the stage's step) this
#: many times; nearer, the moduli (~ overlap^-1.5) inherit its error.
OVERLAP_RESOLUTION_FACTOR = 20.0


def hold_warnings(hold: HoldAnalysis, resolution: float = 0.0,
                  search_spread: float = 0.0) -> list[str]:
    """Where the hold's recipe is known to be biased: a hold shorter than a fitted time
    constant (a hold cannot resolve a tau longer than itself), and a held overlap within
    :data:`OVERLAP_RESOLUTION_FACTOR` of first touch's standard error or of ``resolution``
    (m, the rig's position step). When first touch was not refitted on the ramp (the
    contact search's is used, with no standard error) ``search_spread`` (m, the spread of
    the search's approaches) stands for it."""
    out = []
    taus = [r.tau for f in hold.fits for r in f.relax if math.isfinite(r.tau)]
    if taus and hold.duration < max(taus):
        out.append(f"the hold ({hold.duration:.0f} s) is shorter than the fitted tau "
                   f"({max(taus):.0f} s): a hold cannot resolve a time constant longer than "
                   "itself; hold for several tau")
    held = hold.overlap.held if hold.overlap is not None else hold.depth
    floor = max(hold.overlap.stderr if hold.overlap is not None else 0.0, resolution)
    if hold.overlap is None or hold.overlap.touch is None:
        floor = max(floor, search_spread)
    if floor > 0 and held < OVERLAP_RESOLUTION_FACTOR * floor:
        out.append(f"the held overlap ({held * 1e6:.1f} um) is within "
                   f"{OVERLAP_RESOLUTION_FACTOR:g}x the resolution of first touch "
                   f"({floor * 1e6:.2g} um): the moduli (~ overlap^-1.5) are uncertain by "
                   f"{150 * floor / held:.2g} % or more")
    return out


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
                 params: Mapping[str, Any] | None = None, search_spread: float = 0.0
                 ) -> list[str]:
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
    lines += [f"  WARNING: {w}" for w in hold_warnings(hold, search_spread=search_spread)]
    return lines


def hold_section(hold: HoldAnalysis, index: int, name: str, out: Path,
                 results: Mapping[str, Any] | None = None,
                 params: Mapping[str, Any] | None = None, search_spread: float = 0.0
                 ) -> Section:
    """The report section of a fitted hold; its figure is written to ``out``. With the step's
    ``results`` (run.json), also how the hold ended and the live fit's history."""
    radius = hold.radius
    depth = hold.overlap.held if hold.overlap is not None else hold.depth
    png = f"hold_{index:02d}.png"
    plot_hold_fits(out / png, hold.t, hold.g, hold.fits,
                   f"{name}: G(t) = F / (K delta^1.5), R {radius * 1e3:.3f} mm, "
                   f"delta {depth * 1e3:.3f} mm")
    notes = [f"{len(f.relax)}-term fit: not resolved: {f.reason}; it is drawn dashed and "
             "its values are not a result." for f in hold.fits if not f.is_resolved]
    end = hold_end_line(results or {}, params or {})
    if end:
        notes.append(end[0].upper() + end[1:] + ".")
    notes += [f"Warning: {w}." for w in hold_warnings(hold, search_spread=search_spread)]
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
