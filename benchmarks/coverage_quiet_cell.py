"""Coverage of the hold fit's 95 % intervals over seeds on a grid of load-cell noise, hold,
rate and material, by the cheap path of ``tests/instrument/analysis/quiet_cell.py`` (contact
model -> load-cell chain -> noise -> 14-bit codes -> tare -> ``analyse_hold``; ADR 0270).

    PYTHONPATH=. python benchmarks/coverage_quiet_cell.py OUT.jsonl [SEEDS]
    PYTHONPATH=. python benchmarks/coverage_quiet_cell.py OUT.jsonl SEEDS \
        --cell plate:100:300:0.05 --first-seed 41   # one cell (material:Hz:s:mN), new seeds
    PYTHONPATH=. python benchmarks/coverage_quiet_cell.py --summary OUT.jsonl ...
    PYTHONPATH=. python benchmarks/coverage_quiet_cell.py --figure PNG OUT.jsonl ...

One JSON line per member (z = (fit - truth) / reported s.e. per parameter); ``--summary``
prints, per cell, how many intervals held the truth, the sd of z and the binomial check.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.stats import binom

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gelrig.instrument.physics.paper import PLATES, SHELL
from tests.instrument.analysis.quiet_cell import analysed, z_scores

NOISES = (0.05e-3, 0.1e-3, 0.2e-3, 0.5e-3)
#: (material, terms, rate, hold), in the order run: 1 kHz up to 1000 s, 100 Hz to 3000 s.
CELLS = [("plate", 1, 100.0, 300.0), ("plate", 1, 1000.0, 600.0), ("shell", 2, 100.0, 3000.0),
         ("plate", 1, 100.0, 3000.0), ("plate", 1, 1000.0, 300.0), ("shell", 2, 1000.0, 1000.0)]
MATERIALS = {"plate": PLATES, "shell": SHELL}


def run(out: Path, seeds: int, cell: tuple[str, float, float, float] | None = None,
        first_seed: int = 1) -> None:
    """Members of every cell (or only ``cell``: material, rate, hold, noise N), seeds
    ``first_seed`` .. ``first_seed + seeds - 1``; those already in ``out`` are skipped."""
    done = set()
    if out.exists():
        done = {(r["mat"], r["noise"], r["rate"], r["hold"], r["seed"])
                for r in map(json.loads, out.read_text().splitlines())}
    with out.open("a") as fh:
        for mat, terms, rate, hold in CELLS:
            for noise in NOISES:
                if cell is not None and cell != (mat, rate, hold, noise):
                    continue
                for seed in range(first_seed, first_seed + seeds):
                    if (mat, noise, rate, hold, seed) in done:
                        continue
                    material = MATERIALS[mat]
                    a = analysed(material, noise, rate, hold, seed,
                                 tuple(range(1, terms + 1)))
                    row = {"mat": mat, "noise": noise, "rate": rate, "hold": hold,
                           "seed": seed, "resolved": a.fits[-1].terms_resolved,
                           **z_scores(material, a)}
                    fh.write(json.dumps(row) + "\n")
                    fh.flush()


def _cells(paths: list[str]) -> dict[tuple[str, float, float, float], list[dict]]:
    rows = [json.loads(line) for p in paths for line in Path(p).read_text().splitlines()]
    cells: dict[tuple[str, float, float, float], list[dict]] = defaultdict(list)
    for r in rows:
        cells[(r["mat"], r["rate"], r["hold"], r["noise"])].append(r)
    return dict(sorted(cells.items()))


def figure(png: str, paths: list[str]) -> None:
    """Coverage of each parameter per cell against noise, with the binomial floor."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cells = _cells(paths)
    setups = sorted({k[:3] for k in cells})
    fig, axes = plt.subplots(1, len(setups), figsize=(3.2 * len(setups), 3.4), sharey=True)
    for ax, setup in zip(np.atleast_1d(axes), setups, strict=True):
        noises = sorted(k[3] for k in cells if k[:3] == setup)
        for name in ("G_e", "G_1", "tau_1", "G_2", "tau_2"):
            frac = []
            for noise in noises:
                z = np.array([r[name] for r in cells[(*setup, noise)] if name in r])
                frac.append(np.mean(np.abs(z) <= 1.959963984540054) * 100 if z.size else np.nan)
            if np.isfinite(frac).any():
                ax.plot(np.array(noises) * 1e3, frac, marker="o", label=name)
        n = max(len(cells[(*setup, noise)]) for noise in noises)
        ax.axhline(95, color="k", ls="--", lw=1)
        ax.axhline(binom.ppf(0.025, n, 0.95) / n * 100, color="r", ls=":", lw=1)
        ax.set_xscale("log")
        ax.set_xticks([n * 1e3 for n in NOISES], [f"{n * 1e3:g}" for n in NOISES])
        ax.minorticks_off()
        ax.set_title(f"{setup[0]}, {setup[1]:g} Hz, {setup[2]:g} s (n={n})", fontsize=8)
        ax.set_xlabel("load-cell noise (mN rms)")
        ax.set_ylim(60, 101)
    np.atleast_1d(axes)[0].set_ylabel("95 % interval holds the truth (%)")
    np.atleast_1d(axes)[-1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


def summary(paths: list[str]) -> None:
    cells = _cells(paths)
    for (mat, rate, hold, noise), group in cells.items():
        parts = []
        for name in ("G_e", "G_1", "tau_1", "G_2", "tau_2"):
            z = np.array([r[name] for r in group if name in r])
            if z.size < 2:
                continue
            hits = int(np.sum(np.abs(z) <= 1.959963984540054))
            lo, hi = binom.ppf(0.025, z.size, 0.95), binom.ppf(0.975, z.size, 0.95)
            ok = "ok" if hits >= lo else "LOW"
            parts.append(f"{name} {hits}/{z.size} ({ok}, band {lo:.0f}-{hi:.0f}) "
                         f"sd {z.std(ddof=1):.2f}")
        resolved = sum(1 for r in group if "G_e" in r)
        print(f"{mat} {rate:g} Hz {hold:g} s {noise * 1e3:g} mN: resolved {resolved}/"
              f"{len(group)}; " + "; ".join(parts))


if __name__ == "__main__":
    if sys.argv[1] == "--summary":
        summary(sys.argv[2:])
    elif sys.argv[1] == "--figure":
        figure(sys.argv[2], sys.argv[3:])
    else:
        args = sys.argv[1:]
        only, first = None, 1
        if "--cell" in args:
            i = args.index("--cell")
            mat, rate, hold, noise = args[i + 1].split(":")
            only = (mat, float(rate), float(hold), float(noise) * 1e-3)
            del args[i:i + 2]
        if "--first-seed" in args:
            i = args.index("--first-seed")
            first = int(args[i + 1])
            del args[i:i + 2]
        run(Path(args[0]), int(args[1]) if len(args) > 1 else 40, only, first)
