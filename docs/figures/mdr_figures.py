"""Figures of docs/decisions/0150: the MDR unloading model against the cutoff model.

Run: python docs/figures/mdr_figures.py   (writes docs/figures/mdr_*.png, prints the table)

At the paper's parameters (physics.md 4: the F_h material G_e = 4 kPa, G_l = 5 G_e,
tau = 2000 s, mu = 5e-3, R1 = 9.2 mm, R2 = 9.96 mm, 0.78 mm overlap, the four ladder speeds),
each pass sampled every 1 um of travel as the rheometer simulator does:
- mdr_fh_traces.png: F_h over one pass, both models, every speed;
- mdr_contact_length.png: l_c / l_g against speed, both models (l_c = travel with F_perp > 0);
- mdr_recovery.png: what a second pass meets after a 60 s rest when the MDR state is carried
  (the dent left by the first pass and its recovery), against a fresh contact.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import FloatArray, NormalContact
from gelrig.instrument.physics.mdr import MdrContact
from gelrig.instrument.physics.sliding import SlidingGeometry, resolve_forces
from gelrig.instrument.reports.plots import save_figure

HERE = Path(__file__).resolve().parent
GEOMETRY = SlidingGeometry(paper.R1_SHEAR, paper.R2_SHEAR, paper.DELTA_MAX_SHOWN)
MATERIAL = paper.SHEAR_FH
STEP = 1e-6  # m of travel per sample
MARGIN = 0.3e-3  # m of travel before first touch and after the far psi0
REST = 60.0  # s between passes


def pass_samples(speed: float, t0: float = 0.0) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Times (s), offsets psi (m) and overlaps (m) of one pass from psi0 + MARGIN."""
    start = GEOMETRY.psi0 + MARGIN
    n = round(2 * start / STEP) + 1
    travel = np.arange(n) * STEP
    psi = start - travel
    return t0 + travel / speed, psi, GEOMETRY.overlap(psi)


def contact_length(psi: FloatArray, f_perp: FloatArray) -> float:
    """Travel (m) from the first to the last sample with F_perp > 0."""
    on = np.flatnonzero(f_perp > 0)
    return float(psi[on[0]] - psi[on[-1]]) if on.size else 0.0


def mdr() -> MdrContact:
    return MdrContact(MATERIAL, GEOMETRY.radius, delta_max=GEOMETRY.delta_max)


def main() -> None:
    rows = []
    traces = []
    recovery = []
    for speed in paper.SPEEDS:
        t, psi, delta = pass_samples(speed)
        cut = NormalContact(MATERIAL, GEOMETRY.radius).block(t, delta)
        contact = mdr()
        first = contact.block_detail(t, delta)
        dent = contact.surface
        rest_t = t[-1] + np.linspace(0.0, REST, 61)[1:]
        contact.block(rest_t, np.full(rest_t.size, float(delta[-1])))
        rested = contact.surface
        t2, _, _ = pass_samples(speed, rest_t[-1] + STEP / speed)
        second = contact.block(t2, delta)
        fh = {name: resolve_forces(f, psi, GEOMETRY.h, paper.MU)[0]
              for name, f in (("cutoff", cut), ("mdr", first.force), ("mdr2", second))}
        lc = {name: contact_length(psi, f)
              for name, f in (("cutoff", cut), ("mdr", first.force), ("mdr2", second))}
        rows.append((speed, lc, fh))
        traces.append((speed, psi, fh))
        recovery.append((speed, contact.positions, dent, rested, psi, fh))
    print(f"0.78 mm, l_g = {GEOMETRY.l_g * 1e3:.4f} mm; F_h peak / trough in mN")
    print(f"{'speed m/s':>10s} {'l_c/l_g cut':>12s} {'l_c/l_g MDR':>12s} "
          f"{'l_c/l_g MDR 2nd':>16s} {'trough cut':>11s} {'trough MDR':>11s} "
          f"{'peak cut':>9s} {'peak MDR':>9s} {'peak MDR 2nd':>13s}")
    for speed, lc, fh in rows:
        print(f"{speed:10.3g} {lc['cutoff'] / GEOMETRY.l_g:12.4f} {lc['mdr'] / GEOMETRY.l_g:12.4f} "
              f"{lc['mdr2'] / GEOMETRY.l_g:16.4f} {fh['cutoff'].min() * 1e3:11.3f} "
              f"{fh['mdr'].min() * 1e3:11.3f} {fh['cutoff'].max() * 1e3:9.3f} "
              f"{fh['mdr'].max() * 1e3:9.3f} {fh['mdr2'].max() * 1e3:13.3f}")
    for speed, _x, dent, rested, _, _ in recovery:
        print(f"{speed:10.3g}: dent at the centre after the pass {dent[0] * 1e6:.1f} um, "
              f"after {REST:g} s rest {rested[0] * 1e6:.1f} um")
    _plot_traces(traces)
    _plot_lengths(rows)
    _plot_recovery(recovery)


def _plot_traces(traces: list) -> None:
    fig = Figure(figsize=(10.5, 4.2), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    start = GEOMETRY.psi0 + MARGIN
    for (speed, psi, fh), colour in zip(traces, colours, strict=True):
        theta = (start - psi) * 1e3
        ax.plot(theta, fh["cutoff"] * 1e3, "--", color=colour, lw=1.0)
        ax.plot(theta, fh["mdr"] * 1e3, "-", color=colour, lw=1.4, label=f"{speed:.3g} m/s")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel("travel theta (mm)")
    ax.set_ylabel("F_h (mN)")
    ax.set_title("One pass at 0.78 mm: MDR (solid) and cutoff (dashed), fresh contact")
    ax.legend(loc="upper right", fontsize=8)
    save_figure(fig, HERE / "mdr_fh_traces.png")


def _plot_lengths(rows: list) -> None:
    fig = Figure(figsize=(5.6, 4.0), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    speeds = np.array([r[0] for r in rows])
    for key, label, style in (("cutoff", "cutoff, fresh", "s--"), ("mdr", "MDR, fresh", "o-"),
                              ("mdr2", f"MDR, 2nd pass after {REST:g} s", "^:")):
        ax.plot(speeds, [r[1][key] / GEOMETRY.l_g for r in rows], style, label=label)
    paper_ratio = 1.0 - 219.2e-6 / GEOMETRY.l_g
    ax.axhline(paper_ratio, color="0.4", lw=0.8, label="paper: l_g - l_c = 219 um (speed n/a)")
    ax.set_xscale("log")
    ax.set_xlabel("sliding speed (m/s)")
    ax.set_ylabel("l_c / l_g")
    ax.set_title("Contact length at 0.78 mm")
    ax.legend(fontsize=8)
    save_figure(fig, HERE / "mdr_contact_length.png")


def _plot_recovery(recovery: list) -> None:
    fig = Figure(figsize=(10.5, 4.0), layout="constrained")
    left = fig.add_subplot(1, 2, 1)
    right = fig.add_subplot(1, 2, 2)
    start = GEOMETRY.psi0 + MARGIN
    for speed, x, dent, rested, psi, fh in (recovery[0], recovery[-1]):
        line = left.plot(x * 1e3, dent * 1e6, label=f"{speed:.3g} m/s, end of pass")[0]
        left.plot(x * 1e3, rested * 1e6, ":", color=line.get_color(),
                  label=f"{speed:.3g} m/s, after {REST:g} s")
        theta = (start - psi) * 1e3
        right.plot(theta, fh["mdr"] * 1e3, color=line.get_color(), label=f"{speed:.3g} m/s fresh")
        right.plot(theta, fh["mdr2"] * 1e3, ":", color=line.get_color(),
                   label=f"{speed:.3g} m/s after {REST:g} s (state carried)")
    left.set_xlabel("MDR element position x (mm)")
    left.set_ylabel("surface dent w (um)")
    left.set_title("Dent the pass leaves (centre-line MDR)")
    left.legend(fontsize=7)
    right.axhline(0.0, color="0.6", lw=0.6)
    right.set_xlabel("travel theta (mm)")
    right.set_ylabel("F_h (mN)")
    right.set_title("Second pass: fresh vs. MDR state carried")
    right.legend(fontsize=7)
    save_figure(fig, HERE / "mdr_recovery.png")


if __name__ == "__main__":
    main()
