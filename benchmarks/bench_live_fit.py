"""Cost of the live relaxation fit, and the adaptive hold's honesty under the paper's noise.

Run: python benchmarks/bench_live_fit.py [--study 100]

Cost, on a 3000 s hold at 1 kHz (3e6 samples) of the paper's plate (1 term) and shell (2 terms):
- one refit at the end of the hold (median of 5), against the baseline measured in the same
  run: the offline fit of the same raw samples (``fit_relaxation``, median of 3);
- every refit of a whole hold (at the live fit's cadence), as a fraction of the hold's 3000 s of
  (virtual) wall time, and the same total against the one offline fit.

``--study N``: N simulated adaptive holds (target 2 %; the shell must resolve two terms) per
material at 100 Hz: where they ended, how far the final tau lies from the truth in its stated
standard errors (coverage at 1 and 2 s.e.: about 68 % and 95 % if the rule does not stop on
noise) and its error in percent.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _timing import median_time

from gelrig.instrument.analysis.live_fit import LiveFit, StopRule
from gelrig.instrument.analysis.live_fit_sim import BLOCK, modulus_noise, simulate_hold
from gelrig.instrument.analysis.relaxation import fit_relaxation
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import Material

HOLD, RATE = 3000.0, 1000.0
CASES = (("plate", paper.PLATES, 1), ("shell", paper.SHELL, 2))


def cost(name: str, material: Material, terms: int) -> None:
    rng = np.random.default_rng(1)
    t = np.arange(round(HOLD * RATE)) / RATE
    g = material.modulus(t) + rng.normal(0.0, modulus_noise(), t.size)
    live = LiveFit(terms, HOLD, RATE)
    per_block = round(BLOCK * RATE)
    refits = 0.0
    for start in range(0, t.size, per_block):
        live.add(t[start:start + per_block], g[start:start + per_block])
        elapsed = min(start + per_block, t.size) / RATE
        if live.due(elapsed):
            t0 = time.perf_counter()
            live.refit(elapsed)
            refits += time.perf_counter() - t0
    one = median_time(lambda: live.refit(HOLD), 5)
    offline = median_time(lambda: fit_relaxation(t, g, terms=terms), 3)
    print(f"{name} ({terms} term{'s' if terms > 1 else ''}), 3000 s at 1 kHz: one refit at "
          f"the end {one * 1e3:.1f} ms; offline fit of the same samples {offline * 1e3:.0f} ms "
          f"(ratio {one / offline:.3f})")
    print(f"  {len(live.history) - 5} refits during the hold: {refits:.2f} s in all = "
          f"{refits / HOLD * 100:.3f} % of the hold's wall time; "
          f"{refits / offline:.1f}x the one offline fit")


def study(n: int) -> None:
    for name, material, terms in CASES:
        rule = StopRule(0.02, terms=terms)
        ended, z, err = [], [], []
        true_tau = material.relax[0].tau
        t0 = time.perf_counter()
        for seed in range(n):
            sim = simulate_hold(material, terms, HOLD, 100.0, seed=1000 + seed, rule=rule)
            last = sim.history[-1]
            ended.append(sim.ended if sim.reason == "target" else float("inf"))
            z.append((last.tau - true_tau) / last.stderr["tau_1"])
            err.append((last.tau / true_tau - 1) * 100)
        za = np.abs(np.array(z))
        met = [e for e in ended if e < HOLD + 1]
        print(f"{name}, {n} adaptive holds at 100 Hz ({rule.describe()}), "
              f"{time.perf_counter() - t0:.0f} s:")
        print(f"  ended on target {len(met)}/{n}, median {statistics.median(met):.0f} s, "
              f"range {min(met):.0f}..{max(met):.0f} s" if met else "  never met")
        print(f"  final tau_1 within 1 s.e. of truth {np.mean(za <= 1) * 100:.0f} % "
              f"(68 % expected), within 2 s.e. {np.mean(za <= 2) * 100:.0f} % (95 %); "
              f"mean z {np.mean(z):+.2f}")
        print(f"  tau_1 error: mean {np.mean(err):+.2f} %, sd {np.std(err):.2f} %, worst "
              f"{max(err, key=abs):+.2f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=int, default=0,
                        help="simulated adaptive holds per material (0: cost only)")
    args = parser.parse_args()
    for case in CASES:
        cost(*case)
    if args.study:
        study(args.study)


if __name__ == "__main__":
    main()
