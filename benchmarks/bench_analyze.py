"""Wall time of ``gelrig analyze`` on the paper's simulated runs.

Run: python benchmarks/bench_analyze.py [--repeats 3] [--shear RUN_DIR] [--compression RUN_DIR]

Without run directories it first records the paper's protocols on the built-in simulated
rigs (virtual time; about half a minute): the full shear ladder (5 overlaps x 4 speeds x C/AC
= 40 passes, ~160k samples with the contact search) and the 3000 s hold at 1 kHz (3e6
samples). For each it prints the median wall time of ``analyze_run`` (report, figures,
tables and, for the ladder, the model fit) and its ratio to a baseline measured in the same
run: reading every step's data from the run directory.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from _timing import median_time

from gelrig.analyze_run import analyze_run
from gelrig.instrument.core.store import RunDirectory, read_step


def record(name: str, out: Path) -> Path:
    """The paper's protocol ``name`` on its simulated rig, recorded to ``out``."""
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.protocols.events import RunState
    from gelrig.protocols.host import run_metadata as metadata
    from gelrig.protocols.rigfile import default_rig, load_rig
    from gelrig.protocols.spec import load_protocol, paper_protocol
    from gelrig.terminal import record_run

    protocol = load_protocol(paper_protocol(name))
    spec = load_rig(default_rig(protocol.rig))
    run = RunDirectory.create(out, metadata(protocol, spec, "virtual"))
    state, _ = record_run(protocol, spec, VirtualClock(), run, show=False)
    if state is not RunState.COMPLETED:
        raise SystemExit(f"recording paper:{name} ended {state.value}")
    return out


def read_all(run_dir: Path) -> int:
    run = RunDirectory(run_dir)
    return sum(len(read_step(run.path / s["file"])["t_s"]) for s in run.read_metadata()["steps"])


def bench(label: str, run_dir: Path, out: Path, repeats: int) -> None:
    samples = read_all(run_dir)
    base = median_time(lambda: read_all(run_dir), repeats)
    result = analyze_run(run_dir, out)  # warm-up, and the numbers to show
    full = median_time(lambda: analyze_run(run_dir, out), repeats)
    print(f"{label}: {samples:,} samples; median of {repeats}")
    print(f"  baseline, read the run's data: {base:8.3f} s")
    print(f"  gelrig analyze (report):       {full:8.3f} s   ratio {full / base:6.1f}")
    for fit in result.model_fits.values():
        print(f"  of which the model fit:        {fit.seconds:8.3f} s   ({fit.n_passes} passes, "
              f"{fit.evaluations} model evaluations over "
              f"{fit.extra['trajectory_samples']:,} samples)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--shear", type=Path, default=None, help="a paper:shear run directory")
    parser.add_argument("--compression", type=Path, default=None,
                        help="a paper:compression run directory")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        t0 = time.perf_counter()
        shear = args.shear or record("shear", work / "shear")
        comp = args.compression or record("compression", work / "compression")
        if not (args.shear and args.compression):
            print(f"recorded the simulated runs in {time.perf_counter() - t0:.1f} s")
        bench("shear ladder, 40 passes", shear, work / "out_shear", args.repeats)
        bench("3000 s hold at 1 kHz", comp, work / "out_comp", args.repeats)


if __name__ == "__main__":
    main()
