"""MDR contact throughput against the cutoff model, measured in the same run.

Run: python benchmarks/bench_mdr.py [--repeats 5]

Prints samples/s (median of the repeats) of gelrig.instrument.physics.mdr.MdrContact (300 elements)
and of
gelrig.instrument.physics.contact.NormalContact on the same records, and their ratio (MDR time /
cutoff
time): a 3000 s hold at 1 kHz (3e6 samples, 1 and 2 relaxation terms), one pass of the shear
ladder at 0.78 mm sampled every 1 um of travel (the simulator's sub-step) at the slowest and
fastest speed, the same pass streamed in blocks of 1000 and 100 samples (as a simulator
reads), and the per-sample reference update (MdrContact.step) on part of the pass.

With ``--ladder`` it also runs the paper's full shear ladder through the simulated rig (as
benchmarks/bench_protocols.py does) twice: as shipped (cutoff) and with the rig's
``[simulator] unloading = "mdr"``, and prints both wall times and their ratio.
"""

from __future__ import annotations

import argparse
import statistics
from collections.abc import Callable

import numpy as np
from _timing import median_time

from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold_overlap
from gelrig.instrument.physics.contact import Material, NormalContact
from gelrig.instrument.physics.mdr import MdrContact
from gelrig.instrument.physics.sliding import SlidingGeometry

N_HOLD = 3_000_000
DT_HOLD = 1e-3
TRAVEL_STEP = 1e-6  # m, the rheometer simulator's substep_travel


def _pass(speed: float) -> tuple[np.ndarray, np.ndarray, float]:
    geometry = SlidingGeometry(paper.R1_SHEAR, paper.R2_SHEAR, paper.DELTA_MAX_SHOWN)
    start = geometry.psi0 + 0.2e-3
    dt = TRAVEL_STEP / speed
    t = np.arange(int(2 * start / TRAVEL_STEP) + 1) * dt
    return t, geometry.overlap(start - speed * t), geometry.radius


def _blocks(make: Callable[[], NormalContact | MdrContact], t: np.ndarray, d: np.ndarray,
            size: int) -> None:
    contact = make()
    for i in range(0, t.size, size):
        contact.block(t[i : i + size], d[i : i + size])


def _steps(make: Callable[[], MdrContact], t: np.ndarray, d: np.ndarray) -> None:
    contact = make()
    for a, b in zip(t.tolist(), d.tolist(), strict=True):
        contact.step(a, b)


def _row(name: str, n: int, mdr: float, cut: float | None) -> None:
    ratio = f"{mdr / cut:9.1f}" if cut else f"{'':>9s}"
    cut_rate = f"{n / cut / 1e6:12.2f}" if cut else f"{'':>12s}"
    print(f"{name:44s} {n:>9d} {n / mdr / 1e6:12.3f} {cut_rate} {ratio}")


def _ladder_wall(mdr: bool) -> float:
    """Wall time (s) of the paper's shear ladder on the simulated rig, cutoff or MDR
    (``[simulator] unloading``)."""
    import tempfile
    from pathlib import Path

    from bench_protocols import run_protocol

    with tempfile.TemporaryDirectory() as folder:
        return run_protocol("shear", Path(folder), unloading="mdr" if mdr else "cutoff")[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--ladder", action="store_true",
                        help="also time the paper's shear ladder on the simulated rig")
    options = parser.parse_args()
    repeats = options.repeats
    print(f"median of {repeats} runs; ratio = MDR time / cutoff time on the same samples")
    header = (f"{'record':44s} {'samples':>9s} {'MDR M/s':>12s} {'cutoff M/s':>12s} "
              f"{'ratio':>9s}")
    print(header)
    print("-" * len(header))
    t = np.arange(N_HOLD) * DT_HOLD
    delta = ramp_hold_overlap(t, paper.DEPTH_HOLD, paper.RAMP_SPEED)
    r = paper.R_COMPRESSION
    holds: dict[str, Material] = {"1 term": paper.PLATES, "2 terms": paper.SHELL}
    for label, m in holds.items():
        mdr = median_time(lambda m=m: MdrContact(m, r, delta_max=paper.DEPTH_HOLD)
                          .block_uniform(delta, DT_HOLD), repeats)
        cut = median_time(lambda m=m: NormalContact(m, r).block_uniform(delta, DT_HOLD), repeats)
        _row(f"3000 s hold at 1 kHz, {label}", N_HOLD, mdr, cut)
    m = paper.SHEAR_FH
    for speed in (paper.SPEEDS[0], paper.SPEEDS[-1]):
        tp, dp, rp = _pass(speed)

        def make_mdr(rp: float = rp) -> MdrContact:
            return MdrContact(m, rp, delta_max=paper.DELTA_MAX_SHOWN)

        def make_cut(rp: float = rp) -> NormalContact:
            return NormalContact(m, rp)

        tag = f"pass 0.78 mm at {speed:.3g} m/s"
        for size in (tp.size, 1000, 100):
            name = f"{tag}, whole" if size == tp.size else f"{tag}, blocks of {size}"
            mdr = median_time(lambda s=size, tp=tp, dp=dp, mk=make_mdr: _blocks(mk, tp, dp, s),
                              repeats)
            cut = median_time(lambda s=size, tp=tp, dp=dp, mk=make_cut: _blocks(mk, tp, dp, s),
                              repeats)
            _row(name, tp.size, mdr, cut)
    tp, dp, rp = _pass(paper.SPEEDS[0])
    k = 2000
    ref = median_time(lambda: _steps(lambda: MdrContact(m, rp, delta_max=paper.DELTA_MAX_SHOWN),
                                     tp[:k], dp[:k]), max(1, repeats // 2))
    _row("per-sample reference MdrContact.step", k, ref, None)
    if options.ladder:
        runs = max(1, repeats // 2)
        cut_walls, mdr_walls = [], []
        for _ in range(runs):  # interleaved, so a change in machine load hits both
            cut_walls.append(_ladder_wall(False))
            mdr_walls.append(_ladder_wall(True))
        cut_wall, mdr_wall = statistics.median(cut_walls), statistics.median(mdr_walls)
        print(f"paper shear ladder on the simulated rig, median of {runs}: cutoff "
              f"{cut_wall:.1f} s, MDR {mdr_wall:.1f} s wall, ratio {mdr_wall / cut_wall:.2f}")


if __name__ == "__main__":
    main()
