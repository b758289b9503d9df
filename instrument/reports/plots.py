"""PNG figures of holds and passes (matplotlib's object API on the Agg canvas: no GUI, no Qt)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from gelrig.instrument.analysis.relaxation import RelaxationFit
from gelrig.instrument.physics.contact import FloatArray


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Render on the Agg canvas and write a PNG, making the folder if needed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=dpi)
    return path


def plot_relaxation(
    path: str | Path,
    series: Sequence[tuple[str, FloatArray, FloatArray, Sequence[RelaxationFit]]],
) -> Path:
    """G(t) over the hold with its fits; one panel per (label, t, G, fits)."""
    fig = Figure(figsize=(5.2 * len(series), 4.0), layout="constrained")
    for i, (label, t, g, fits) in enumerate(series):
        ax = fig.add_subplot(1, len(series), i + 1)
        step = max(1, t.size // 3000)
        ax.plot(t[::step], g[::step] / 1e3, ".", ms=2, color="tab:blue", label="back-calculated G")
        for fit, colour in zip(fits, ("tab:red", "goldenrod"), strict=False):
            terms = len(fit.relax)
            taus = ", ".join(f"{r.tau:.0f} s" for r in fit.relax)
            ax.plot(t, fit.model(t) / 1e3, color=colour, lw=1.5,
                    label=f"{terms}-term fit: G_e {fit.g_e:.0f} Pa, tau {taus}")
        ax.set_xlabel("time in hold (s)")
        ax.set_ylabel("G (kPa)")
        ax.set_title(label)
        ax.legend(fontsize=8)
    return save_figure(fig, path)


def plot_passes(
    path: str | Path,
    passes: Sequence[tuple[str, FloatArray, FloatArray, FloatArray]],
    title: str = "",
) -> Path:
    """F_h and F_v against travel theta for several passes: (label, theta_m, f_h_N, f_v_N)."""
    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    ax_h = fig.add_subplot(1, 2, 1)
    ax_v = fig.add_subplot(1, 2, 2)
    for label, theta, f_h, f_v in passes:
        ax_h.plot(theta * 1e3, f_h * 1e3, label=label)
        ax_v.plot(theta * 1e3, f_v * 1e3, label=label)
    ax_h.axhline(0.0, color="0.6", lw=0.8)
    ax_h.set_xlabel("theta (mm)")
    ax_h.set_ylabel("F_h (mN)")
    ax_v.set_xlabel("theta (mm)")
    ax_v.set_ylabel("F_v (mN)")
    ax_h.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def plot_force(path: str | Path, t: FloatArray, force: FloatArray, title: str = "") -> Path:
    """Force (mN) against time (s), decimated for the picture."""
    fig = Figure(figsize=(6.0, 3.6), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    step = max(1, t.size // 5000)
    ax.plot(t[::step], np.asarray(force)[::step] * 1e3, lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("force (mN)")
    if title:
        ax.set_title(title)
    return save_figure(fig, path)
