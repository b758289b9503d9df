"""Compare every hold across the steps of one or more runs: ``series_report(run_dirs, out)``.

A composition root like :mod:`gelrig.analyze_run`, which it runs on each run (without the
ladder model fit) into ``OUT/runs/``; then one row per hold (ramp_hold steps and the holds
found in steps of any kind): G_e, G_1, tau_1 (and a creep's tau_c) with 95 % intervals
against strain and hold length, as ``series.csv``, ``series.png`` and ``report.html``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from matplotlib.figure import Figure

from gelrig.analyze_run import AnalysisResult, analyze_run
from gelrig.instrument.analysis.found_holds import hold_row, relaxation_row
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.reports.any_run import HOLD_COLUMNS
from gelrig.instrument.reports.document import Column, Section, Table, write_report
from gelrig.instrument.reports.plots import save_figure

SERIES_COLUMNS = (Column("run", "run"), Column("step", "step"), Column("step_name", "name"),
                  *HOLD_COLUMNS)


@dataclass
class SeriesResult:
    """What ``series_report`` produced: the rows (SI), the report and the CSV."""

    rows: list[dict[str, object]]
    report_path: Path
    csv_path: Path
    summary: str


def series_rows(result: AnalysisResult) -> list[dict[str, object]]:
    """One row per hold of an analysed run, in step order."""
    rows = []
    run = result.run_dir.name
    for index in sorted(set(result.holds) | set(result.found)):
        name = result.step_names.get(index, (f"step {index}", "?"))[0]
        head: dict[str, object] = {"run": run, "step": index, "step_name": name}
        if index in result.holds:
            hold = result.holds[index]
            overlap = hold.overlap.held if hold.overlap is not None else hold.depth
            rows.append(head | relaxation_row(hold.fits[-1] if hold.fits else None, overlap,
                                              result.diameter, hold.duration))
        for found in result.found.get(index, []):
            rows.append(head | hold_row(found, result.diameter))
    return rows


def _num(row: Mapping[str, object], key: str) -> float:
    """A row's number, NaN when it holds none."""
    value = row.get(key)
    return float(value) if isinstance(value, int | float) else math.nan


def plot_series(path: Path, rows: Sequence[dict[str, object]]) -> Path:
    """tau_1, G_e and G_1 with their 95 % intervals against strain (top) and hold length
    (bottom), one marker per run."""
    fig = Figure(figsize=(11.0, 7.0), layout="constrained")
    axes = fig.subplots(2, 3)
    runs = sorted({str(r["run"]) for r in rows})
    for row_axes, (across, label) in zip(axes, (("strain", "strain (overlap / diameter)"),
                                                ("hold_s", "hold length (s)")), strict=True):
        for ax, (name, unit) in zip(row_axes, (("tau_1", "s"), ("G_e", "Pa"), ("G_1", "Pa")),
                                    strict=True):
            for k, run in enumerate(runs):
                pts = [r for r in rows if r["run"] == run and math.isfinite(_num(r, name))]
                if not pts:
                    continue
                x = [_num(r, across) for r in pts]
                y = [_num(r, name) for r in pts]
                lo = [v - _num(r, f"{name}_lo") for v, r in zip(y, pts, strict=True)]
                hi = [_num(r, f"{name}_hi") - v for v, r in zip(y, pts, strict=True)]
                ax.errorbar(x, y, yerr=[[0.0 if math.isnan(e) else e for e in lo],
                                        [0.0 if math.isnan(e) else e for e in hi]],
                            fmt="os^dv"[k % 5], capsize=3, label=run)
            ax.set_xlabel(label)
            ax.set_ylabel(f"{name} ({unit})")
    if runs:
        axes[0][0].legend(fontsize=7)
    return save_figure(fig, path, dpi=90)


def series_report(run_dirs: Sequence[str | Path], out_dir: str | Path) -> SeriesResult:
    """Analyse each run into ``out_dir/runs/`` and compare all their holds. Raises
    ConfigError naming the first folder that is not a run (before anything is analysed)."""
    out = Path(out_dir)
    paths = [Path(p) for p in run_dirs]
    for path in paths:
        if not (path / "run.json").is_file():
            raise ConfigError("RUN_DIR", str(path), "is not a run folder (no run.json)")
    rows: list[dict[str, object]] = []
    lines = [f"gelrig series: {len(paths)} run(s)"]
    for k, path in enumerate(paths):
        result = analyze_run(path, out / "runs" / f"{k:02d}_{path.name}", fit_model=False)
        found = series_rows(result)
        rows += found
        lines.append(f"  {path}: {len(found)} hold(s); report {result.report_path}")
    for r in rows:
        if r["resolved"]:
            text = "; ".join(f"{n} {_num(r, n):.4g} [{_num(r, n + '_lo'):.4g}, "
                             f"{_num(r, n + '_hi'):.4g}]" for n in ("tau_1", "G_e", "G_1", "tau_c")
                             if math.isfinite(_num(r, n)))
            if r["not_resolved"]:
                text += f" ({r['not_resolved']})"
        else:
            text = f"not resolved: {r['not_resolved']}"
        lines.append(f"  {r['run']} step {r['step']} {r['hold']} strain "
                     f"{_num(r, 'strain'):.4f}, {_num(r, 'hold_s'):.0f} s: {text}")
    out.mkdir(parents=True, exist_ok=True)
    figure = plot_series(out / "series.png", rows)
    table = Table("Every hold (SI; 95 % intervals value +- 1.96 s.e.)", SERIES_COLUMNS, rows,
                  "series.csv")
    section = Section("Holds across steps and runs", [
        "tau_1, G_e and G_1 of every hold against strain and hold length; a creep hold's G_1 "
        "and tau_1 come from its retardation time tau_c and the recorded loading. A hold not "
        "resolved shows no values and says why."],
        [(figure.name, "tau_1, G_e, G_1 against strain and against hold length.")],
        [table])
    summary = "\n".join(lines)
    page = write_report(out, "gelrig series", summary, [section])
    return SeriesResult(rows, page, out / "series.csv", summary + f"\nreport: {page.resolve()}")
