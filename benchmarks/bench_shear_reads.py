"""Per-read cost of the simulated shear cell (the physics behind every MCR 501 stream read).

Run: python benchmarks/bench_shear_reads.py [--repeats 7]

A ShearCell streams at 10 Hz while the arm sweeps 16 mm at the slowest and the fastest
ladder speed, read every 1.7 s of virtual time (as the ladder step reads), once with the
spheres in contact over the sweep (overlap 0.78 mm) and once apart (1 mm gap). Prints the
median CPU microseconds per read for the default (each pass a fresh contact: nothing is
integrated while apart) and the ratio to the baseline measured in the same run, the same cell
with ``carry_history`` (the hereditary state integrated through every node).
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.mcr501.physics import ShearCell

SPEEDS = (2.38e-5, 2.37e-4)
READ_EVERY = 1.7  # s of virtual time
TRAVEL = 16e-3  # m


def per_read(overlap: float, carry: bool) -> float:
    """CPU seconds per read over both sweeps."""
    cfg = SimConfig(acceleration=50.0, carry_history=carry)
    total, reads = 0.0, 0
    for speed in SPEEDS:
        start = cfg.lower_angle - (TRAVEL / 2) / cfg.arm
        cell = ShearCell(replace(cfg, start_angle=start, start_gap=cfg.touch_gap - overlap), 0.0)
        cell.start_stream(0.0, 0.1)
        cell.set_speed(0.0, speed / cfg.arm)
        t, end = 0.0, TRAVEL / speed
        c0 = time.process_time()
        while t < end:
            t += READ_EVERY
            cell.advance(t)
            cell.samples.clear()
            reads += 1
        total += time.process_time() - c0
    return total / reads


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    for label, overlap in (("in contact", 0.78e-3), ("apart", -1e-3)):
        fresh, carried = [], []
        for _ in range(args.repeats):  # interleaved, so both see the same machine load
            fresh.append(per_read(overlap, False))
            carried.append(per_read(overlap, True))
        f, c = statistics.median(fresh), statistics.median(carried)
        print(f"shear cell, {label}: {f * 1e6:.0f} us CPU per read (fresh contact); "
              f"carry_history baseline {c * 1e6:.0f} us; ratio {f / c:.2f}", flush=True)


if __name__ == "__main__":
    main()
