"""Wall time of the paper's full protocols on the simulated rigs in virtual time.

Run: python benchmarks/bench_protocols.py [--repeats 3]

Every byte crosses the real drivers and transports (APT over a pyserial URL, the official
nidaqmx client over gRPC, pyvisa-py over TCP). Prints the median wall time, the lab-time /
wall-time ratio, and the ratio to a baseline measured in the same run: the contact model
alone computing the same experiment (3e6 force samples; 40 modelled passes), i.e. what the
instrument stack costs on top of the physics. Targets: compression < 5 s, ladder < 30 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

from _timing import median_time

from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.store import RunDirectory
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold
from gelrig.instrument.physics.sliding import SlidingGeometry, shear_pass
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import load_protocol, paper_protocol
from gelrig.terminal import record_run


def run_protocol(kind: str, folder: Path, **truth: object) -> tuple[float, float]:
    """(wall s, lab s) of one full paper protocol, recorded to disk; ``truth`` overrides
    fields of the rig's simulated sample (e.g. ``unloading="mdr"``)."""
    t0 = time.perf_counter()
    clock = VirtualClock()
    rig = load_rig(default_rig(kind))
    if truth:
        rig = dataclasses.replace(rig, simulator=dataclasses.replace(rig.simulator, **truth))
    state, _ = record_run(load_protocol(paper_protocol(kind)), rig, clock,
                       RunDirectory.create(folder, {}), show=False)
    if state is not RunState.COMPLETED:
        raise SystemExit(f"{kind} protocol ended {state.value}")
    return time.perf_counter() - t0, clock.now()


def model_compression() -> None:
    ramp_hold(paper.R_COMPRESSION, paper.DEPTH_HOLD, paper.RAMP_SPEED, paper.HOLD, paper.PLATES,
              dt=1e-3)


def model_ladder() -> None:
    for k in range(5):
        geometry = SlidingGeometry(paper.R1_SHEAR, paper.R2_SHEAR, 0.38e-3 + 1e-4 * k)
        for speed in paper.SPEEDS:
            for _ in range(2):
                shear_pass(geometry, paper.SHEAR_FH, speed, paper.MU, dt=0.1,
                           margin=8e-3 - geometry.psi0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    repeats = parser.parse_args().repeats
    baselines = {"compression": median_time(model_compression, repeats),
                 "shear": median_time(model_ladder, repeats)}
    labels = {"compression": "paper compression (search + 6 % ramp + 3000 s hold at 1 kHz)",
              "shear": "paper shear (contact search + 5 x 4 x 2 ladder)"}
    with tempfile.TemporaryDirectory() as tmp:
        for kind in ("compression", "shear"):
            results = [run_protocol(kind, Path(tmp) / f"{kind}-{i}") for i in range(repeats)]
            wall = statistics.median(r[0] for r in results)
            lab = results[0][1]
            print(f"{labels[kind]}: median wall {wall:.2f} s over {repeats} runs, lab time "
                  f"{lab:,.0f} s, lab/wall {lab / wall:,.0f}x; model-only baseline "
                  f"{baselines[kind]:.3f} s, ratio {wall / baselines[kind]:.1f}x")


if __name__ == "__main__":
    main()
