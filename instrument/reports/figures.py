"""PNG figures of the analysis report (matplotlib's object API on the Agg canvas, no pyplot).

Inputs are SI arrays; axis labels carry the display units (mm, mN, kPa).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from matplotlib.figure import Figure

from gelrig.instrument.analysis.relaxation import RelaxationFit
from gelrig.instrument.core.binning import bin_means
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.reports.plots import save_figure

#: Bin means drawn for a long record (its samples are drawn thinned).
_DRAWN_BINS = 2000
_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
            "tab:pink", "tab:gray", "tab:olive", "tab:cyan")


def plot_hold_fits(
    path: str | Path, t: FloatArray, g: FloatArray, fits: Sequence[RelaxationFit], title: str
) -> Path:
    """G(t) over the hold with its Prony fits (top) and the fits' residuals (bottom)."""
    fig = Figure(figsize=(7.0, 6.0), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    tb, gb = bin_means(t, g, _DRAWN_BINS)
    step = max(1, t.size // 4000)
    top.plot(t[::step], g[::step] / 1e3, ".", ms=1.5, color="0.6", label="back-calculated G")
    for fit, colour in zip(fits, ("tab:red", "tab:blue"), strict=False):
        taus = ", ".join(f"{r.g:.0f} Pa/{r.tau:.0f} s" for r in fit.relax)
        ok = fit.is_resolved
        label = (f"{len(fit.relax)}-term: G_e {fit.g_e:.0f} Pa; {taus}" if ok else
                 f"{len(fit.relax)}-term: not resolved")
        style = "-" if ok else "--"
        top.plot(tb, fit.model(tb) / 1e3, style, color=colour, lw=1.4, label=label)
        bottom.plot(tb, (gb - fit.model(tb)), style, color=colour, lw=0.9,
                    label=f"{len(fit.relax)}-term" + (f", rmse {fit.rmse:.1f} Pa" if ok
                                                      else ", not resolved"))
    bottom.axhline(0.0, color="0.3", lw=0.6)
    top.set_ylabel("G (kPa)")
    top.set_title(title)
    top.legend(fontsize=8)
    bottom.set_xlabel("time in hold (s)")
    bottom.set_ylabel("residual, bin means (Pa)")
    bottom.legend(fontsize=8)
    return save_figure(fig, path, dpi=100)


@dataclass(frozen=True)
class PassCurve:
    """One pass to draw: label, lab theta (m), F_h and F_v (N), optional markers (m)."""

    label: str
    theta: FloatArray
    f_h: FloatArray
    f_v: FloatArray
    marks: tuple[float, ...] = ()


def plot_pass_curves(
    path: str | Path, curves: Sequence[PassCurve], title: str, centre: float = 0.0
) -> Path:
    """F_h (left) and F_v (right) against theta - centre; vertical ticks at the markers."""
    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    ax_h, ax_v = fig.subplots(1, 2)
    for i, c in enumerate(curves):
        colour = _COLOURS[i % len(_COLOURS)]
        x = (c.theta - centre) * 1e3
        ax_h.plot(x, c.f_h * 1e3, lw=0.9, color=colour, label=c.label)
        ax_v.plot(x, c.f_v * 1e3, lw=0.9, color=colour, label=c.label)
        for m in c.marks:
            ax_h.axvline((m - centre) * 1e3, color=colour, lw=0.7, ls=":")
    ax_h.axhline(0.0, color="0.5", lw=0.6)
    ax_h.set_xlabel("theta from the centre of l_g (mm)")
    ax_h.set_ylabel("F_h in the frame of the motion (mN)")
    ax_v.set_xlabel("theta from the centre of l_g (mm)")
    ax_v.set_ylabel("F_v (mN)")
    ax_h.legend(fontsize=7)
    fig.suptitle(title)
    return save_figure(fig, path, dpi=100)


def plot_vs_speed(
    path: str | Path,
    series: Mapping[str, tuple[FloatArray, FloatArray]],
    ylabel: str,
    title: str,
    reference: float | None = None,
    reference_label: str = "",
) -> Path:
    """One marker line per series (e.g. per overlap) of a quantity against sliding speed."""
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    for i, (label, (speed, value)) in enumerate(series.items()):
        ax.plot(speed, value, "o-", ms=4, lw=1.0, color=_COLOURS[i % len(_COLOURS)], label=label)
    if reference is not None:
        ax.axhline(reference, color="0.3", ls="--", lw=0.9, label=reference_label)
    ax.set_xscale("log")
    ax.set_xlabel("sliding speed v (m/s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    return save_figure(fig, path, dpi=100)


@dataclass(frozen=True)
class FitPanel:
    """One pass of the model-fit figure: measured and model forces against theta."""

    title: str
    theta: FloatArray
    measured: FloatArray
    model: FloatArray


def plot_fit_grid(
    path: str | Path, panels: Sequence[FitPanel], columns: int, ylabel: str, title: str
) -> Path:
    """Small multiples of data (grey dots) against the fitted model (red line)."""
    rows = max(1, -(-len(panels) // columns))
    # A fixed grid: constrained layout costs seconds on tens of axes.
    width, height = 2.0 * columns + 0.6, 1.6 * rows + 0.7
    fig = Figure(figsize=(width, height))
    fig.subplots_adjust(left=0.6 / width, right=0.99, bottom=0.45 / height,
                        top=1.0 - 0.65 / height, wspace=0.35, hspace=0.55)
    axes = fig.subplots(rows, columns, squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.set_axis_off()
    for ax, p in zip(axes.flat, panels, strict=False):
        step = max(1, p.theta.size // 400)
        ax.plot(p.theta[::step] * 1e3, p.measured[::step] * 1e3, ".", ms=1.2, color="0.55")
        ax.plot(p.theta[::step] * 1e3, p.model[::step] * 1e3, color="tab:red", lw=0.8)
        ax.set_title(p.title, fontsize=7)
        ax.tick_params(labelsize=6)
        ax.locator_params(nbins=3)
    for ax in axes[-1]:
        ax.set_xlabel("theta (mm)", fontsize=7)
    for ax in axes[:, 0]:
        ax.set_ylabel(ylabel, fontsize=7)
    fig.suptitle(title, fontsize=10)
    return save_figure(fig, path, dpi=100)
