"""Start-up time of the ``gelrig`` command line: ``gelrig --help`` and ``gelrig plan --help``.

Run: python benchmarks/bench_cli.py [--repeats 15]

Each command runs as a whole new process (``python -m gelrig.cli ...`` on this source tree,
what the ``gelrig`` console script runs), in turn with the baseline ``python -c pass`` (the
interpreter's own start-up, measured in the same run), after one warm-up of each. Prints the
median wall time of each and its ratio to the baseline (the median of the ratios of each
round, so a drift of the machine's speed cancels).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

COMMANDS = {
    "python -c pass": ["-c", "pass"],
    "gelrig --help": ["-m", "gelrig.cli", "--help"],
    "gelrig plan --help": ["-m", "gelrig.cli", "plan", "--help"],
}


def wall(args: list[str], env: dict[str, str]) -> float:
    """Wall time (s) of one ``python ARGS`` process; it must succeed."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], cwd=ROOT, env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    repeats = parser.parse_args().repeats
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for args in COMMANDS.values():
        wall(args, env)  # warm up the file cache
    for _ in range(repeats):
        for name, args in COMMANDS.items():
            times[name].append(wall(args, env))
    base = times["python -c pass"]
    print(f"whole processes, median of {repeats} rounds (each round runs every command once)")
    print(f"{'command':22s} {'median s':>9s} {'x python -c pass':>17s}")
    for name, runs in times.items():
        ratio = statistics.median(t / b for t, b in zip(runs, base, strict=True))
        print(f"{name:22s} {statistics.median(runs):9.3f} {ratio:17.2f}")


if __name__ == "__main__":
    main()
