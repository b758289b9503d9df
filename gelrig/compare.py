"""Runs side by side (``gelrig runs ROOT --compare RUN RUN...``): a table of their results
with intervals and an overlay plot of their main curves (ADR 0370).

The curves: force against time in each hold of a compression run (``ramp_hold``, ``creep``,
``load_unload``: time from the step's start); F_h and F_v per pass of a shear ladder (the
largest |F_h| and F_v of each pass, baseline-corrected as the analysis does).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from gelrig.catalog import LoadedRun, flat_results

#: Step kinds whose force against time is a compression run's main curve.
HOLD_KINDS = ("ramp_hold", "creep", "load_unload")
#: Step kinds that record shear passes.
LADDER_KINDS = ("speed_ladder",)
#: Display scale of units: SI -> (factor, shown unit).
_DISPLAY = {"m": (1e3, "mm"), "m/s": (1e6, "um/s")}


def _fmt(value: float | None, scale: float) -> str:
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value * scale:.4g}"


def cell(result: Mapping[str, Any] | None) -> str:
    """One result as ``7734 [7612, 7856] Pa`` (95 % interval when it has one)."""
    if result is None:
        return ""
    scale, unit = _DISPLAY.get(str(result.get("unit")), (1.0, str(result.get("unit") or "")))
    text = _fmt(result.get("value"), scale)
    if result.get("lo") is not None:
        text += f" [{_fmt(result['lo'], scale)}, {_fmt(result['hi'], scale)}]"
    return f"{text} {unit}".rstrip()


def compare_rows(entries: Sequence[Mapping[str, Any]]) -> list[list[str]]:
    """The comparison table: a header row (``result``, then each run's folder name), a row
    per run field (sample, operator, protocol, status, started), then a row per result any
    run has (``<step>/<quantity>``), in the order they first appear."""
    results = [flat_results(e) for e in entries]
    keys: list[str] = []
    for found in results:
        keys.extend(k for k in found if k not in keys)
    rows = [["result", *[str(e.get("name")) for e in entries]]]
    for field in ("sample", "operator", "protocol", "status", "started"):
        rows.append([field, *[str(e.get(field) or "") for e in entries]])
    for key in keys:
        rows.append([key, *[cell(found.get(key)) for found in results]])
    return rows


def _arm(meta: Mapping[str, Any]) -> float:
    from gelrig.analyze_run import _arm as arm_of

    return arm_of(meta, [])


class HoldCurve(NamedTuple):
    """One hold step's curve: time from the step's start (s), force (N), stage position (m;
    None when the step did not record it)."""

    step: str
    t: Any
    force: Any
    position: Any


def hold_curves(run: LoadedRun) -> list[HoldCurve]:
    """The force curves of a compression run's holds (``HOLD_KINDS``), in recorded order."""
    out = []
    for step in run:
        if step.kind in HOLD_KINDS and {"t_s", "force_N"} <= set(step.columns):
            t, f = step["t_s"], step["force_N"]
            if t.size:
                z = step["position_m"] if "position_m" in step.columns else None
                out.append(HoldCurve(step.name, t - t[0], f, z))
    return out


def pass_peaks(run: LoadedRun) -> list[tuple[Any, Any, Any]]:
    """Each shear ladder's (pass index, largest |F_h|, largest F_v) arrays (N), baseline-
    corrected as the analysis does; a pass too short to read is left out."""
    import numpy as np

    from gelrig.instrument.analysis.shear_analysis import pass_forces, split_passes

    out = []
    arm: float | None = None  # read once a ladder is found (the analysis is slow to import)
    for step in run:
        if step.kind not in LADDER_KINDS:
            continue
        if arm is None:
            arm = _arm(run.meta)
        index, f_h, f_v = [], [], []
        for recorded in split_passes(step.columns):
            try:
                forces = pass_forces(recorded, arm)
            except Exception:  # a pass too short to read: left out of the curve
                continue
            index.append(recorded.index)
            f_h.append(float(np.max(np.abs(forces.f_h[forces.moving]))))
            f_v.append(float(np.max(forces.f_v[forces.moving])))
        out.append((np.asarray(index), np.asarray(f_h), np.asarray(f_v)))
    return out


def overlay_plot(runs: Sequence[LoadedRun], path: str | Path) -> tuple[Path, list[str]]:
    """Write the overlay PNG of ``runs``; returns its path and notes on runs that have no
    curve to draw."""
    from matplotlib.figure import Figure

    from gelrig.instrument.reports.plots import save_figure

    holds = {id(r): hold_curves(r) for r in runs}
    ladders = {id(r): pass_peaks(r) for r in runs}
    panels = (["hold"] if any(holds.values()) else []) + (
        ["F_h", "F_v"] if any(ladders.values()) else [])
    notes = [f"{r.path.name}: no hold or ladder recorded" for r in runs
             if not holds[id(r)] and not ladders[id(r)]]
    fig = Figure(figsize=(5.5 * max(1, len(panels)), 4.2), layout="constrained")
    axes = {name: fig.add_subplot(1, max(1, len(panels)), i + 1)
            for i, name in enumerate(panels or ["hold"])}
    colours = [f"C{k % 10}" for k in range(len(runs))]
    for run, colour in zip(runs, colours, strict=True):
        label = f"{run.path.name} ({run.sample or 'no sample'})"
        for k, (_, t, f, _z) in enumerate(holds[id(run)]):
            step = max(1, t.size // 4000)
            axes["hold"].plot(t[::step], f[::step] * 1e3, color=colour, lw=1.0,
                              ls=("-", "--", ":", "-.")[k % 4],
                              label=label if k == 0 else None)
        for k, (index, f_h, f_v) in enumerate(ladders[id(run)]):
            axes["F_h"].plot(index, f_h * 1e3, "o-", color=colour, ms=3,
                             label=label if k == 0 else None)
            axes["F_v"].plot(index, f_v * 1e3, "o-", color=colour, ms=3,
                             label=label if k == 0 else None)
    titles = {"hold": ("time from the step's start (s)", "force (mN)", "force in each hold"),
              "F_h": ("pass", "largest |F_h| (mN)", "F_h per pass"),
              "F_v": ("pass", "largest F_v (mN)", "F_v per pass")}
    for name, ax in axes.items():
        x, y, title = titles[name]
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.set_title(title)
        if ax.lines:
            ax.legend(fontsize=7)
    return save_figure(fig, path), notes
