"""Memory per run in one process: the paper compression protocol run N times through the
scripting API (``gelrig.open_rig("compression").run(...)``), RSS after each run (issue 32:
about 10 MB more per run).

Run: python benchmarks/bench_run_memory.py [--runs 12] [--hold 3000] [--checkout DIR]

Each configuration runs in a fresh process: the code as it is, and a baseline in the same
session with ``release_freed_memory`` (what the run host calls as a run ends) turned into a
no-op, i.e. the allocator keeping what runs freed. Prints RSS after each run, the median
growth per run over runs 2..N (MB per run) with its ratio to the growth of the first run
(imports, caches, the simulators' first buffers), and the spread of RSS over runs 2..N.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, sys, shutil, tempfile
from pathlib import Path
import gelrig
from gelrig.protocols import host
from gelrig.protocols.spec import paper_protocol

runs, hold, keep_freed = int(sys.argv[1]), sys.argv[2], sys.argv[3] == "1"
if keep_freed:
    host.release_freed_memory = lambda: None

def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise SystemExit("no /proc/self/status")

text = paper_protocol("compression").read_text().replace('hold = "3000 s"', f'hold = "{hold} s"')
tmp = Path(tempfile.mkdtemp(prefix="gelrig-bench-"))
(tmp / "p.toml").write_text(text)
out = [rss_mb()]
with gelrig.open_rig("compression") as rig:
    for i in range(runs):
        result = rig.run(tmp / "p.toml", out=tmp / f"run{i}")
        if not result.ok:
            raise SystemExit(f"run {i}: {result.state}: {result.reason}")
        shutil.rmtree(tmp / f"run{i}")
        out.append(rss_mb())
shutil.rmtree(tmp)
print(json.dumps(out))
"""


def measure(runs: int, hold: float, keep_freed: bool, root: Path = ROOT) -> list[float]:
    """RSS (MB) before the first run and after each run, in a fresh process running the
    code of the checkout ``root``."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    proc = subprocess.run([sys.executable, "-W", "ignore", "-c", CHILD, str(runs), f"{hold:g}",
                           "1" if keep_freed else "0"], capture_output=True, text=True,
                          env=env, check=False)
    if proc.returncode != 0:
        raise SystemExit(proc.stderr.strip().splitlines()[-1] if proc.stderr else "failed")
    values: list[float] = json.loads(proc.stdout.strip().splitlines()[-1])
    return values


def report(label: str, rss: list[float]) -> float:
    growth = [b - a for a, b in itertools.pairwise(rss)]
    first, later = growth[0], growth[1:]
    per_run = statistics.median(later)
    spread = max(rss[2:]) - min(rss[2:])
    print(f"{label}: RSS before {rss[0]:.0f} MB, after run 1 {rss[1]:.0f} MB, after run "
          f"{len(growth)} {rss[-1]:.0f} MB")
    print("  after each run: " + ", ".join(f"{v:.0f}" for v in rss[1:]))
    ratio = per_run / first if first else float("nan")
    print(f"  growth per run (median of runs 2..{len(growth)}): {per_run:+.1f} MB "
          f"({ratio:+.3f}x the first run's {first:+.1f} MB); RSS spread over runs "
          f"2..{len(growth)}: {spread:.0f} MB; whole: {(rss[-1] - rss[1]) / (len(growth) - 1):+.2f}"
          " MB per run after the first")
    return per_run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=12)
    parser.add_argument("--hold", type=float, default=3000.0, help="hold (s) at 1 kHz")
    parser.add_argument("--checkout", type=Path, default=None,
                        help="also measure the code of another checkout (e.g. main)")
    args = parser.parse_args()
    if args.runs < 3:
        raise SystemExit("--runs: at least 3")
    if not Path("/proc/self/status").exists():
        raise SystemExit("needs Linux (/proc/self/status)")
    print(f"paper compression, {args.hold:g} s hold at 1 kHz, {args.runs} runs in one process "
          "through gelrig.open_rig(...).run(...)")
    now = report("release_freed_memory after each run (as shipped)",
                 measure(args.runs, args.hold, keep_freed=False))
    base = report("baseline: freed memory kept by the allocator",
                  measure(args.runs, args.hold, keep_freed=True))
    print(f"median growth per run: {now:+.1f} MB against {base:+.1f} MB in the baseline")
    if args.checkout is not None:
        report(f"the checkout {args.checkout}", measure(args.runs, args.hold, False,
                                                        args.checkout.resolve()))


if __name__ == "__main__":
    main()
