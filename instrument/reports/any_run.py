"""The report's part for a step of any kind: its recorded columns, and the holds found in it.

Formatting only: the holds come from :mod:`gelrig.instrument.analysis.found_holds`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from gelrig.instrument.analysis.found_holds import FoundHold, hold_row
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.reports.document import Column, Section, Table
from gelrig.instrument.reports.figures import plot_hold_fits
from gelrig.instrument.reports.hold import hold_warnings
from gelrig.instrument.reports.plots import save_figure

#: Samples drawn per curve at most (thinned evenly).
_DRAWN = 5000

HOLD_COLUMNS = (
    Column("hold", "hold"), Column("strain", "strain", digits=4),
    Column("overlap_m", "overlap (mm)", 1e3), Column("hold_s", "hold (s)", digits=4),
    Column("G_e", "G_e (Pa)", digits=5), Column("G_e_lo", "G_e 95 % low", digits=5),
    Column("G_e_hi", "G_e 95 % high", digits=5),
    Column("G_1", "G_1 (Pa)", digits=4), Column("G_1_lo", "G_1 95 % low", digits=4),
    Column("G_1_hi", "G_1 95 % high", digits=4),
    Column("tau_1", "tau_1 (s)", digits=4), Column("tau_1_lo", "tau_1 95 % low", digits=4),
    Column("tau_1_hi", "tau_1 95 % high", digits=4),
    Column("tau_c", "creep tau_c (s)", digits=4), Column("tau_c_lo", "tau_c 95 % low", digits=4),
    Column("tau_c_hi", "tau_c 95 % high", digits=4),
    Column("resolved", "resolved"), Column("not_resolved", "not resolved: why"),
)


def numeric_columns(columns: Mapping[str, FloatArray]) -> list[str]:
    """The columns worth drawing against time: numeric, not time itself, not all NaN."""
    out = []
    for name, values in columns.items():
        v = np.asarray(values)
        if name == "t_s" or v.ndim != 1 or not np.issubdtype(v.dtype, np.number):
            continue
        if v.size and np.isfinite(v.astype(float)).any():
            out.append(name)
    return out


def plot_columns(path: str | Path, columns: Mapping[str, FloatArray], title: str) -> Path | None:
    """Every numeric column against time, one panel each (None without a time column)."""
    if "t_s" not in columns:
        return None
    names = numeric_columns(columns)
    if not names:
        return None
    t = np.asarray(columns["t_s"], dtype=float)
    step = max(1, t.size // _DRAWN)
    fig = Figure(figsize=(7.0, 1.7 * len(names) + 0.6), layout="constrained")
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name in zip(axes, names, strict=True):
        ax.plot(t[::step], np.asarray(columns[name], dtype=float)[::step], lw=0.8)
        ax.set_ylabel(name, fontsize=8)
    axes[-1].set_xlabel("t (s)")
    axes[0].set_title(title)
    return save_figure(fig, path, dpi=90)


def plot_force_position(path: str | Path, columns: Mapping[str, FloatArray], title: str,
                        holds: Sequence[FoundHold] = ()) -> Path | None:
    """Force (mN) against plate position (mm), the holds marked; None without the columns."""
    if not {"position_m", "force_N"} <= set(columns):
        return None
    z = np.asarray(columns["position_m"], dtype=float)
    f = np.asarray(columns["force_N"], dtype=float)
    step = max(1, z.size // _DRAWN)
    fig = Figure(figsize=(6.0, 4.0), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(z[::step] * 1e3, f[::step] * 1e3, lw=0.8, color="0.4", label="record")
    for k, hold in enumerate(holds):
        s = hold.segment
        ax.plot(z[s.start:s.end:step] * 1e3, f[s.start:s.end:step] * 1e3, ".", ms=2,
                label=f"hold {k + 1}: {hold.kind}")
    ax.set_xlabel("plate position (mm)")
    ax.set_ylabel("force (mN)")
    ax.set_title(title)
    if holds:
        ax.legend(fontsize=8)
    return save_figure(fig, path, dpi=90)


def plot_creep(path: str | Path, hold: FoundHold, title: str) -> Path | None:
    """The creep (overlap against time in the hold) with the fitted model."""
    fit = hold.creep
    if fit is None:
        return None
    fig = Figure(figsize=(6.0, 4.0), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(fit.t, np.cbrt(fit.x) ** 2 * 1e3, ".", ms=3, color="0.5", label="overlap (bins)")
    label = ("model: not resolved" if not fit.is_resolved else
             f"model: G_e {fit.values['G_e']:.0f} Pa, tau_c {fit.values['tau_c']:.3g} s")
    ax.plot(fit.t, np.cbrt(np.maximum(fit.x_model, 0)) ** 2 * 1e3,
            "-" if fit.is_resolved else "--", color="tab:red", label=label)
    ax.set_xlabel("time in hold (s)")
    ax.set_ylabel("overlap (mm)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    return save_figure(fig, path, dpi=90)


def hold_line(hold: FoundHold, k: int, diameter: float) -> str:
    """One hold in one line: where, how long, and its values or why not resolved."""
    s = hold.segment
    where = (f"hold {k}: {hold.kind} at t {s.t0:.1f} s for {s.duration:.0f} s, overlap "
             f"{hold.overlap * 1e3:.4f} mm (strain {hold.overlap / diameter:.4f}), "
             f"force {hold.force * 1e3:.3f} mN")
    row = hold_row(hold, diameter)
    if not row["resolved"]:
        return f"{where}: not resolved: {row['not_resolved']}"
    parts = []
    for name, unit in (("G_e", "Pa"), ("G_1", "Pa"), ("tau_1", "s"), ("tau_c", "s")):
        value = row.get(name)
        if isinstance(value, float) and math.isfinite(value):
            parts.append(f"{name} {value:.4g} {unit} [{row[name + '_lo']:.4g}, "
                         f"{row[name + '_hi']:.4g}]")
    text = f"{where}: " + "; ".join(parts)
    if row["not_resolved"]:
        text += f" (G_1, tau_1 not resolved: {row['not_resolved']})"
    warnings = hold.creep.warnings if hold.creep is not None else []
    if hold.relaxation is not None:
        warnings = hold_warnings(hold.relaxation)
    return text + "".join(f"; WARNING: {w}" for w in warnings)


def step_section(index: int, name: str, kind: str, columns: Mapping[str, FloatArray],
                 holds: Sequence[FoundHold], diameter: float, out: Path) -> Section:
    """A step's section: its columns against time, force against plate position, every hold
    found with its fit (figures written to ``out``)."""
    section = Section(f"Step {index}: {name} ({kind})", [
        f"{len(numeric_columns(columns))} recorded columns, "
        f"{len(next(iter(columns.values()))) if columns else 0} samples. Holds are found "
        "wherever they are: the plate still within the stage's resolution while in contact "
        "(relaxation; fitted as a ramp_hold's hold) or the force held while the plate moves "
        "(creep; x = delta^1.5 = F/(K G_e) - B exp(-t/tau_c), G_1 and tau_1 from B and the "
        "recorded loading); 95 % intervals are value +- 1.96 s.e."])
    prefix = f"step_{index:02d}"
    drawn = plot_columns(out / f"{prefix}_columns.png", columns, f"{name}: recorded columns")
    if drawn is not None:
        section.figures.append((drawn.name, "Every recorded column against time."))
    drawn = plot_force_position(out / f"{prefix}_force_position.png", columns,
                                f"{name}: force against plate position", holds)
    if drawn is not None:
        section.figures.append((drawn.name, "Force against plate position, holds marked."))
    for k, hold in enumerate(holds, 1):
        section.paragraphs.append(hold_line(hold, k, diameter))
        if hold.relaxation is not None and hold.relaxation.fits:
            png = f"{prefix}_hold_{k}.png"
            plot_hold_fits(out / png, hold.relaxation.t, hold.relaxation.g,
                           hold.relaxation.fits, f"{name}, hold {k}: G(t)")
            section.figures.append((png, f"Hold {k}: back-calculated G(t) and its fits."))
        if hold.creep is not None:
            drawn = plot_creep(out / f"{prefix}_creep_{k}.png", hold, f"{name}, hold {k}: creep")
            if drawn is not None:
                section.figures.append((drawn.name, f"Hold {k}: creep and the model."))
    if holds:
        section.tables.append(Table("Holds found (SI; 95 % intervals)", HOLD_COLUMNS,
                                    [hold_row(h, diameter) for h in holds],
                                    f"{prefix}_holds.csv"))
    return section
