"""A shear ladder killed mid-ladder (SIGKILL) and resumed against the same ladder uninterrupted:
the same seed, the same fit (issue 32, item 10).

Run: ``.venv/bin/python benchmarks/bench_resumed_ladder.py [--seeds 20] [--overlaps 2]
[--out DIR]``

Per seed: the paper's shear protocol (its deepest ``--overlaps`` overlaps, all four speeds,
C and AC) on the built-in shear rig with ``[simulator] seed`` set, recorded by ``gelrig run``
twice, as a person would: once through; once SIGKILLed (the whole process group) once the
ladder has flushed a random 40-80 % of the uninterrupted ladder's samples, then ``gelrig
resume`` (which runs the ladder again from its start, after the killed attempt's last
sample). Both are analysed as ``gelrig analyze`` does (the ladder-wide model fit:
one term, cutoff unloading, the rig's radii). For each fitted parameter it prints, over the
seeds: the median and largest |resumed - uninterrupted| / s.e. (the s.e. of the two fits
combined in quadrature), the mean signed difference over its standard error of the mean
(a systematic shift shows there), and how often each run's 95 % interval holds the truth.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: The fitted parameters compared, and their truth on the built-in rig.
TRUTH = {"G_e": 4000.0, "G_1": 20000.0, "tau_1": 2000.0, "mu": 5e-3}
#: Fraction of the uninterrupted ladder's samples after which the other run is killed.
KILL_AT = (0.4, 0.8)


def gelrig(*args: str, cwd: Path, wait: bool = True) -> Any:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    command = [sys.executable, "-m", "gelrig.cli", *args]
    if wait:
        return subprocess.run(command, cwd=cwd, env=env, text=True, capture_output=True,
                              check=False)
    return subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def files(folder: Path, seed: int, overlaps: int) -> tuple[Path, Path]:
    """The reduced paper protocol and the built-in shear rig with ``seed``."""
    from gelrig.protocols.rigfile import default_rig
    from gelrig.protocols.spec import paper_protocol

    text = paper_protocol("shear").read_text()
    first = 0.38 + 0.1 * (5 - overlaps)  # the deepest overlaps kept
    assert 'overlaps = 5' in text and 'first_overlap = "0.38 mm"' in text
    text = text.replace("overlaps = 5", f"overlaps = {overlaps}").replace(
        'first_overlap = "0.38 mm"', f'first_overlap = "{first:.2f} mm"')
    protocol = folder / "ladder.toml"
    protocol.write_text(text)
    rig = default_rig("shear").read_text()
    assert "\nseed = 1\n" in rig
    rig_file = folder / "rig.toml"
    rig_file.write_text(rig.replace("\nseed = 1\n", f"\nseed = {seed}\n"))
    return protocol, rig_file


def fit(run: Path, rig: Path) -> dict[str, tuple[float, float, float, float]]:
    """name -> (value, s.e., lo, hi) of the ladder-wide model fit of ``run`` (the radii of
    ``rig``'s simulated spheres)."""
    from gelrig.analyze_run import analyze_run
    from gelrig.protocols.resolve import resolve_rig
    from gelrig.protocols.rigfile import ShearRigSpec

    spec = resolve_rig(str(rig))
    assert isinstance(spec, ShearRigSpec)
    sim = spec.simulator
    result = analyze_run(run, run / "analysis", r1=sim.r1, r2=sim.r2, terms=1,
                         unloading="cutoff")
    (_, model), = result.model_fits.items()
    return {e.name: (e.value, e.stderr, e.lo, e.hi) for e in model.estimates}


def wait_for_rows(run: Path, rows: int, proc: subprocess.Popen[str]) -> None:
    """Until the ladder (step 1) of the run recording into ``run`` has ``rows`` samples
    flushed (read as the run writes them), or the process ends."""
    from gelrig.instrument.core.errors import GelrigError
    from gelrig.instrument.core.store import step_extent

    while proc.poll() is None:
        time.sleep(0.5)
        try:
            steps = json.loads((run / "run.json").read_text())["steps"]
            if len(steps) > 1 and step_extent(run / steps[1]["file"])[0] >= rows:
                return
        except (OSError, ValueError, KeyError, GelrigError):
            continue  # not there yet, or caught mid-write


def one_seed(seed: int, overlaps: int, folder: Path, rng: random.Random) -> dict[str, Any]:
    protocol, rig = files(folder, seed, overlaps)
    done = gelrig("run", str(protocol), "--rig", str(rig), "--out", "whole", cwd=folder)
    if done.returncode != 0:
        raise RuntimeError(f"seed {seed}: uninterrupted run exited {done.returncode}: "
                           f"{done.stderr.strip()[-300:]}")
    fraction = rng.uniform(*KILL_AT)
    total = json.loads((folder / "whole" / "run.json").read_text())["steps"][1]["samples"]
    proc = gelrig("run", str(protocol), "--rig", str(rig), "--out", "killed", cwd=folder,
                  wait=False)
    try:
        wait_for_rows(folder / "killed", int(fraction * total), proc)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    meta = json.loads((folder / "killed" / "run.json").read_text())
    running = [s["index"] for s in meta["steps"] if s["status"] == "running"]
    resumed = gelrig("resume", "killed", cwd=folder)
    if resumed.returncode != 0:
        raise RuntimeError(f"seed {seed}: resume exited {resumed.returncode}: "
                           f"{resumed.stderr.strip()[-300:]}")
    return {"seed": seed, "killed_in_step": running, "kill_fraction": fraction,
            "whole": fit(folder / "whole", rig), "resumed": fit(folder / "killed", rig)}


def report(rows: list[dict[str, Any]]) -> None:
    ladder = [r for r in rows if r["killed_in_step"] == [1]]
    print(f"\n{len(rows)} seeds, {len(ladder)} killed while the ladder recorded")
    print("| parameter | median abs(diff) / s.e. of one fit | median abs(diff) / s.e. of "
          "the difference | largest | mean diff / its s.e. | truth in 95 % interval: "
          "uninterrupted / resumed | sd of error / s.e.: uninterrupted / resumed |")
    print("|---|---|---|---|---|---|---|")
    for name, truth in TRUTH.items():
        z, one, signed = [], [], []
        holds = {"whole": 0, "resumed": 0}
        errors: dict[str, list[float]] = {"whole": [], "resumed": []}
        for r in ladder:
            (a, sa, lo_a, hi_a), (b, sb, lo_b, hi_b) = r["whole"][name], r["resumed"][name]
            se = math.hypot(sa, sb)
            z.append(abs(b - a) / se)
            one.append(abs(b - a) / sa)
            signed.append((b - a) / se)
            holds["whole"] += lo_a <= truth <= hi_a
            holds["resumed"] += lo_b <= truth <= hi_b
            errors["whole"].append((a - truth) / sa)
            errors["resumed"].append((b - truth) / sb)
        if not z:
            continue
        sem = statistics.stdev(signed) / math.sqrt(len(signed)) if len(signed) > 1 else math.nan
        print(f"| {name} | {statistics.median(one):.2f} | {statistics.median(z):.2f} | "
              f"{max(z):.2f} | "
              f"{statistics.mean(signed) / sem if sem else math.nan:+.2f} | "
              f"{holds['whole']}/{len(ladder)} / {holds['resumed']}/{len(ladder)} | "
              f"{_sd(errors['whole']):.2f} / {_sd(errors['resumed']):.2f} |")


def _sd(values: list[float]) -> float:
    return statistics.stdev(values) if len(values) > 1 else math.nan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--overlaps", type=int, default=2, choices=range(1, 6))
    parser.add_argument("--out", default=None, help="keep the runs and rows.json here")
    parser.add_argument("--report", default=None, metavar="ROWS.json",
                        help="only print the table of an earlier run's rows.json")
    args = parser.parse_args()
    if args.report:
        report(json.loads(Path(args.report).read_text()))
        return
    rng = random.Random(20261125)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        base = (Path(args.out) if args.out else Path(scratch)).resolve()
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            folder = base / f"seed-{seed}"
            folder.mkdir(parents=True, exist_ok=True)
            started = time.monotonic()
            row = one_seed(seed, args.overlaps, folder, rng)
            rows.append(row)
            print(f"seed {seed}: killed at {row['kill_fraction']:.2f} in step "
                  f"{row['killed_in_step']}; " + ", ".join(
                      f"{n} {row['whole'][n][0]:.5g} / {row['resumed'][n][0]:.5g}"
                      for n in TRUTH) + f" ({time.monotonic() - started:.0f} s)", flush=True)
            (base / "rows.json").write_text(json.dumps(rows, indent=1))
    report(rows)


if __name__ == "__main__":
    main()
