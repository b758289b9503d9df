"""README figure: the live fit's tau and its uncertainty against hold time, plate and shell.

Run: python docs/figures/live_fit_figure.py  (writes docs/figures/live_fit.png)

One simulated 3000 s hold at 100 Hz of each of the paper's materials with the rig's force
noise (instrument/analysis/live_fit_sim.py), refitted as the ``ramp_hold`` step does. Top row: tau_1
(and, in the shell, tau_2) with a band of one standard error; the dashed line is the truth.
Bottom row: each tau's relative standard error now (solid) and forecast at 3000 s (dotted),
the 2 % target, and where the adaptive hold (``until = 0.02``; the shell with
``until_terms = 2``) would have stopped.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from gelrig.instrument.analysis.live_fit import StopRule
from gelrig.instrument.analysis.live_fit_sim import simulate_hold
from gelrig.instrument.physics import paper

OUT = Path(__file__).with_name("live_fit.png")
TARGET = 0.02


def main() -> None:
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharex=True)
    for col, (name, material, terms) in enumerate(
            (("plate (1 term)", paper.PLATES, 1), ("shell (2 terms)", paper.SHELL, 2))):
        rule = StopRule(TARGET, terms=terms)
        sim = simulate_hold(material, terms, paper.HOLD, 100.0, seed=7)
        stop = next((s.elapsed for i, s in enumerate(sim.history)
                     if rule.done(sim.history[:i + 1])), None)
        top, bottom = axes[0, col], axes[1, col]
        for k, truth in enumerate((r.tau for r in material.relax), 1):
            pts = [(s.elapsed, s.relax[k - 1].tau, s.stderr.get(f"tau_{k}", np.nan),
                    s.relative.get(f"tau_{k}", np.nan), s.forecast.get(f"tau_{k}", np.nan))
                   for s in sim.history if len(s.relax) >= k]
            if not pts:
                continue
            t, tau, err, rel, fc = (np.array(x) for x in zip(*pts, strict=True))
            line, = top.plot(t, tau, label=f"tau_{k}")
            top.fill_between(t, tau - err, tau + err, color=line.get_color(), alpha=0.25)
            top.axhline(truth, color=line.get_color(), ls="--", lw=0.8)
            bottom.semilogy(t, rel * 100, color=line.get_color(), label=f"tau_{k} now")
            bottom.semilogy(t, fc * 100, color=line.get_color(), ls=":",
                            label=f"tau_{k} forecast at 3000 s")
        bottom.axhline(TARGET * 100, color="k", lw=0.8, label="target 2 %")
        for ax in (top, bottom):
            if stop is not None:
                ax.axvline(stop, color="r", lw=1.0)
        top.set_ylim(0, 2.5 * material.relax[0].tau)
        if stop is not None:
            top.annotate(f"adaptive hold stops: {stop:.0f} s", (stop, top.get_ylim()[1]),
                         xytext=(4, -12), textcoords="offset points", color="r", fontsize=8)
        top.set_title(f"{name}: live fit of one simulated hold")
        top.set_ylabel("tau (s), band: 1 s.e.")
        bottom.set_ylim(0.05, 100)
        bottom.set_ylabel("relative s.e. of tau (%)")
        bottom.set_xlabel("hold time (s)")
        top.legend(fontsize=8, loc="upper right")
        bottom.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(OUT, dpi=110)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
