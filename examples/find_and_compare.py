"""Find a week of runs of one sample and compare their holds (ADR 0370).

Every ``gelrig run`` records its sample, operator, note and tags (``--sample gel-A1
--operator ada --tag cure2h``) and is indexed in ``ROOT/.gelrig-runs.sqlite``. This script
lists the completed runs of a sample started in the last ``DAYS`` days, prints their fitted
values with 95 % intervals and draws the force of each hold against time::

    python examples/find_and_compare.py runs gel-A1 --days 7 --out holds.png

The same from the command line: ``gelrig runs runs --sample gel-A1 --since 7d`` and
``gelrig runs runs --compare RUN RUN ...``.
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")  # a file, no window
import matplotlib.pyplot as plt

import gelrig


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", nargs="?", default="runs")
    parser.add_argument("sample", nargs="?", default="gel-A1")
    parser.add_argument("--days", type=float, default=7.0)
    parser.add_argument("--out", default="holds.png")
    args = parser.parse_args(argv)

    runs = gelrig.runs(args.root, sample=args.sample, status="completed",
                       since=f"{args.days:g}d")
    fits = [c for c in runs.columns if c.endswith("G_e") or c.endswith("tau_1")]
    print(runs[["name", "operator", "started", *fits]].to_string(index=False))

    fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
    for path in runs.path:
        run = gelrig.load_run(path)
        for hold in (step for step in run if step.kind == "ramp_hold"):
            t = hold["t_s"] - hold["t_s"][0]
            ax.plot(t, hold["force_N"] * 1e3, lw=1, label=f"{run.path.name} ({hold.name})")
    ax.set_xlabel("time from the step's start (s)")
    ax.set_ylabel("force (mN)")
    ax.legend(fontsize=7)
    fig.savefig(args.out, dpi=110)
    print(f"{len(runs)} run(s) of {args.sample}; plot: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
