"""Time from a frozen instrument to ``gelrig run``'s one line, per instrument (issue 32).

Run: ``.venv/bin/python benchmarks/bench_frozen_stop.py [--repeats N] [--only kdc101,...]``

Each instrument is served as a separate ``gelrig sim serve`` process (KDC101 over
``socket://``, USB-6001 over the NI gRPC Device Server API, MCR 501 over pyvisa TCP); the
run is started on the real clock, the instrument frozen with SIGSTOP once the run records,
and the wall time from the freeze to the terminal's line (``...; details: ...``) and to the
process's exit is taken (an unconfirmed stop's retries are given up by a Ctrl-C 2.5 s after
the line, so the exit time is the line plus that). Prints the medians, the line, and the
safe stop's own wall time from run.json.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.frozen_runs import FrozenRun, frozen_run

INSTRUMENTS = ("kdc101", "usb6001", "mcr501")


def measure(instrument: str, repeats: int) -> list[FrozenRun]:
    runs = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            runs.append(frozen_run(instrument, Path(folder),
                                   give_up_after=None if instrument == "usb6001" else 2.5))
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", default=",".join(INSTRUMENTS),
                        help="comma-separated: " + ", ".join(INSTRUMENTS))
    args = parser.parse_args()
    for instrument in args.only.split(","):
        runs = measure(instrument, args.repeats)
        to_line = statistics.median(r.to_line for r in runs)
        to_exit = statistics.median(r.to_exit for r in runs)
        stop_s = statistics.median(float(r.meta.get("safe_state", {}).get("wall_s", 0.0))
                                   for r in runs)
        print(f"{instrument}: freeze -> line median {to_line:.2f} s "
              f"({', '.join(f'{r.to_line:.2f}' for r in runs)}), -> exit {to_exit:.2f} s, "
              f"safe stop {stop_s:.2f} s")
        print(f"  {runs[-1].line.split('; details:')[0]}")


if __name__ == "__main__":
    main()
