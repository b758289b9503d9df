"""Wall time of `gelrig plan`'s rehearsal of the paper protocols on the rigs' twins.

Run: python benchmarks/bench_rehearsal.py [--repeats 3] [--with-run] [--only shear]

The twin is built by gelrig.factory.build_twin (each instrument's simulator, the rheometer and
the force input in process) and the protocol runs through the same Runner, steps and drivers
as a run, counting instead of recording. Prints the median wall and CPU time, the lab/wall
ratio, and the ratio to a baseline measured in the same run: the contact model alone computing
the same experiment (as in bench_protocols.py). ``--with-run`` also times a full recorded
virtual run of each (the drivers over their served transports, HDF5 on disk), which is what a
rehearsal saves. Targets: compression < 2 s, shear < 5 s. Then one more rehearsal under
tracemalloc: its peak allocation against the bytes of the columns it counts (a rehearsal
counts samples, it keeps none; target < 150 MB).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path

from _timing import median_time
from bench_protocols import model_compression, model_ladder, run_protocol

from gelrig.factory import build_twin
from gelrig.protocols.rehearsal import rehearse
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import load_protocol, paper_protocol


def rehearsal(kind: str) -> tuple[float, float, float]:
    """(wall s, CPU s, lab s) of one rehearsal, twin built and closed included."""
    spec, protocol = load_rig(default_rig(kind)), load_protocol(paper_protocol(kind))
    c0, t0 = time.process_time(), time.perf_counter()
    twin = build_twin(spec)
    try:
        report = rehearse(twin, protocol)
    finally:
        twin.close()
    if not report.ok:
        raise SystemExit(f"{kind} rehearsal failed: {report.failure()}")
    return time.perf_counter() - t0, time.process_time() - c0, report.total


def peak_memory(kind: str) -> tuple[float, int]:
    """(peak bytes the rehearsal allocated above what it started with, bytes of the columns
    a run would record): tracemalloc, which numpy's arrays report to."""
    spec, protocol = load_rig(default_rig(kind)), load_protocol(paper_protocol(kind))
    twin = build_twin(spec)
    try:
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        report = rehearse(twin, protocol)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
        twin.close()
    return peak, report.bytes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--with-run", action="store_true")
    parser.add_argument("--only", choices=("compression", "shear"),
                        help="time one protocol (e.g. to compare two checkouts, run by run)")
    args = parser.parse_args()
    baselines = {"compression": median_time(model_compression, args.repeats),
                 "shear": median_time(model_ladder, args.repeats)}
    targets = {"compression": 2.0, "shear": 5.0}
    for kind in (args.only,) if args.only else ("compression", "shear"):
        results = [rehearsal(kind) for _ in range(args.repeats)]
        wall = statistics.median(r[0] for r in results)
        cpu = statistics.median(r[1] for r in results)
        lab = results[0][2]
        line = (f"paper {kind} rehearsal: median wall {wall:.2f} s (CPU {cpu:.2f} s) over "
                f"{args.repeats}, lab time {lab:,.0f} s, lab/wall {lab / wall:,.0f}x; "
                f"model-only baseline {baselines[kind]:.3f} s, ratio {wall / baselines[kind]:.1f}x"
                f"; target < {targets[kind]:g} s")
        if args.with_run:
            with tempfile.TemporaryDirectory() as tmp:
                run = statistics.median(run_protocol(kind, Path(tmp) / f"r{i}")[0]
                                        for i in range(args.repeats))
            line += f"; full recorded run {run:.2f} s ({run / wall:.1f}x the rehearsal)"
        print(line, flush=True)
        peak, recorded = peak_memory(kind)
        print(f"paper {kind} rehearsal: peak memory {peak / 1e6:.1f} MB allocated (tracemalloc) "
              f"for {recorded / 1e6:.1f} MB of columns counted, ratio {peak / recorded:.3f}; "
              f"target < 150 MB", flush=True)


if __name__ == "__main__":
    main()
