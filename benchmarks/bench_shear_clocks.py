"""The shear ladder on every clock (issue 24, item 6): l_g, l_c and mu per level, paced against
virtual, over seeds, beside the virtual clock's own seed-to-seed spread.

Run: python benchmarks/bench_shear_clocks.py [--clocks virtual,paced:100] [--seeds 1,2,3]
[--overlaps 2] [--speeds "2.38e-5 m/s,2.37e-4 m/s"] [--json rows.json]

Runs the paper's shear protocol with a short ladder (``--overlaps`` levels from the paper's
first, ``--speeds``, 10 s waits) on the built-in simulated shear rig, once per clock and seed,
and prints per seed the contact search's touch gap and, per level, each clock's l_g, l_c/l_g
and mu relative to the virtual run of the same seed; then the mean and standard deviation
of those differences over the seeds, and the standard deviation over the seeds of the virtual
runs themselves (the noise a difference is to be judged against: two clocks sample the noise
at other instants, so a paced run is another draw of it).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from pathlib import Path

import numpy as np

from gelrig.clock_check import record_ladder_levels
from gelrig.instrument.core.errors import GelrigError

KEYS = (("touch_gap_m", "touch gap", 1e6, "um"), ("l_g_m", "l_g", None, "%"),
        ("l_c_over_l_g", "l_c/l_g", None, "%"), ("mu", "mu", None, "%"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clocks", default="virtual,paced:100")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--overlaps", type=int, default=2)
    ap.add_argument("--speeds", default="2.38e-5 m/s,2.37e-4 m/s")
    ap.add_argument("--json", default=None, help="also write every run's rows here")
    args = ap.parse_args()
    clocks = args.clocks.split(",")
    seeds = [int(s) for s in args.seeds.split(",")]
    speeds = tuple(s.strip() for s in args.speeds.split(","))
    runs: dict[tuple[str, int], list[dict[str, float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            for i, clock in enumerate(clocks):
                try:
                    runs[clock, seed] = record_ladder_levels(
                        Path(tmp) / f"s{seed}c{i}", clock, args.overlaps, speeds, seed=seed)
                except GelrigError as exc:  # a failed run is reported, not averaged over
                    print(f"{clock} seed {seed}: FAILED: {exc}", flush=True)
                    runs[clock, seed] = []
    ref = clocks[0]
    if args.json:
        Path(args.json).write_text(json.dumps({f"{c} {s}": rows for (c, s), rows in runs.items()}))
    levels = sorted({(r["overlap_m"], r["speed_m_s"]) for rows in runs.values() for r in rows})
    print(f"{len(seeds)} seeds, {len(levels)} levels; differences against {ref} of the same "
          "seed")
    for (clock, seed), rows in runs.items():
        missing = set(levels) - {(r["overlap_m"], r["speed_m_s"]) for r in rows}
        if missing:
            print(f"  {clock} seed {seed}: no result for levels {sorted(missing)}")
    for clock in clocks[1:]:
        print(f"\n{clock}:")
        for key, name, scale, unit in KEYS:
            for level in (levels[:1] if key == "touch_gap_m" else levels):
                diffs, refs = [], []
                for seed in seeds:
                    a, b = _at(runs[clock, seed], level, key), _at(runs[ref, seed], level, key)
                    diffs.append((a - b) * scale if scale else (a / b - 1) * 100)
                    refs.append(b)
                r = np.array(refs)[np.isfinite(refs)]
                spread = float(np.std(r, ddof=1)) if r.size > 1 else math.nan
                spread = spread * scale if scale else spread / float(np.mean(r)) * 100
                d = np.array(diffs)[np.isfinite(diffs)]
                lv = "" if key == "touch_gap_m" else (
                    f" {level[0] * 1e3:.2f}mm {level[1]:.3g}m/s")
                print(f"  {name + lv:<28s} diff {' '.join(f'{x:+7.3f}' for x in diffs)} {unit};"
                      f" mean {d.mean():+7.3f} sd {d.std(ddof=1) if d.size > 1 else math.nan:6.3f}"
                      f"; {ref} seed-to-seed sd {spread:6.3f} {unit}")


def _at(rows: list[dict[str, float]], level: tuple[float, float], key: str) -> float:
    """``key`` of the row of ``level`` (NaN if the run has none)."""
    for r in rows:
        if (r["overlap_m"], r["speed_m_s"]) == level:
            return float(r[key])
    return math.nan

if __name__ == "__main__":
    main()
