"""Accuracy of first touch and G_e through the whole simulated compression rig.

Run: python benchmarks/bench_first_touch.py [--seeds 10] [--hold "600 s"]

Records the paper's contact search (3 approaches) and ramp to 6 % with a hold of ``--hold``
on the built-in simulated rig (virtual time) once per noise seed, analyses each run with
``gelrig analyze`` and prints, against the truth of protocols/rigs/compression.toml
(first touch 6.2 mm, G_e 7146 Pa): the bias (mean error over the seeds), spread and worst
error of the first touch from the ramp refit and, as the baseline measured in the same runs,
from the contact search; then G_e's error with the measured overlap and with the nominal
depth from the contact search's touch (docs/decisions/0160).
"""

from __future__ import annotations

import argparse
import re
import statistics
import tempfile
from pathlib import Path

from gelrig.analyze_run import analyze_run
from gelrig.instrument.analysis.hold_analysis import analyse_hold
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.store import RunDirectory, read_step
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import record_run

TOUCH, G_E = 6.2e-3, 7146.0


def one_run(folder: Path, seed: int, hold: str) -> tuple[float, float, float, float, float]:
    """(search touch, refitted touch, G_e measured overlap, G_e nominal depth, the refitted
    touch's reported standard error) of one seed."""
    folder.mkdir(parents=True)
    rig = folder / "rig.toml"
    rig.write_text(re.sub(r"(?m)^seed = \d+", f"seed = {seed}",
                          default_rig("compression").read_text()))
    steps = [{"kind": "compression_contact_search", "confirm": 2, "rate": "100 Hz"},
             {"kind": "ramp_hold", "hold": hold, "rate": "100 Hz", "terms": 1}]
    protocol = parse_protocol({"protocol": {"name": "touch", "rig": "compression"},
                               "sample": {"diameter": "18.63 mm"},  # the simulated sphere
                               "step": steps})
    spec = load_rig(rig)
    run = RunDirectory.create(folder / "run", {"protocol": protocol.table, "rig": spec.table})
    record_run(protocol, spec, VirtualClock(), run, show=False)
    hold_result = analyze_run(run.path, folder / "out").holds[1]
    overlap = hold_result.overlap
    assert overlap is not None
    step = run.read_metadata()["steps"][1]
    cols = read_step(run.step_file(step))
    nominal = analyse_hold(cols["t_s"], cols["force_N"], cols["delta_m"], 18.63e-3 / 2,
                           step["results"]["depth_m"], terms=(1,))
    reported = overlap.touch.stderr if overlap.touch is not None else float("nan")
    return (overlap.recorded_touch, overlap.first_touch, hold_result.fits[0].g_e,
            nominal.fits[0].g_e, reported)


def describe(label: str, errors: list[float], scale: float, unit: str) -> str:
    return (f"  {label:<34s} bias {statistics.fmean(errors) * scale:+7.3f} {unit}, sd "
            f"{statistics.stdev(errors) * scale:6.3f} {unit}, worst "
            f"{max(errors, key=abs) * scale:+7.3f} {unit}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--hold", default="600 s")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.seeds + 1):
            rows.append(one_run(Path(tmp) / str(seed), seed, args.hold))
    search, refit, g_meas, g_nom, stderr = ([r[i] for r in rows] for i in range(5))
    print(f"{args.seeds} runs of the simulated compression rig (seeds 1..{args.seeds}), hold "
          f"{args.hold}; truth: first touch {TOUCH * 1e3} mm, G_e {G_E:g} Pa")
    print("first touch:")
    print(describe("contact search (baseline)", [z - TOUCH for z in search], 1e6, "um"))
    print(describe("refitted on the ramp", [z - TOUCH for z in refit], 1e6, "um"))
    print(f"  refit's reported standard error: median {statistics.median(stderr) * 1e6:.3f} "
          f"um; spread / reported: {statistics.stdev(refit) / statistics.median(stderr):.2f}")
    sd_ratio = statistics.stdev(refit) / statistics.stdev(search)
    print(f"  ratio of spreads, refit / search: {sd_ratio:.3f}")
    print("G_e:")
    print(describe("nominal depth (baseline)", [g / G_E - 1 for g in g_nom], 100, "%"))
    print(describe("measured overlap", [g / G_E - 1 for g in g_meas], 100, "%"))


if __name__ == "__main__":
    main()
