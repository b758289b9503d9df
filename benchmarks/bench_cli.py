"""The ``gelrig`` command line as whole processes: start-up, and what a command costs beyond its
work (issue 31).

Run: python benchmarks/bench_cli.py [--repeats 5] [--only startup,plan,run,terminal]

Every command runs as a whole new process (``python -m gelrig.cli ...`` on this source tree,
what the ``gelrig`` console script runs) in turn with its baseline (so both see the same
machine load), after one warm-up of each; each figure is the median of ``--repeats`` rounds,
and each ratio the median of the rounds' ratios. CPU is user + system of the process and its
children (``os.wait4``), which a loaded machine disturbs far less than wall time.

- startup: ``gelrig --help`` and ``gelrig plan --help`` against ``python -c pass`` (wall s).
- plan: ``gelrig plan paper:compression`` (CPU s) against its rehearsal in process (the CPU
  of one rehearsal in a process that has run one before: the work alone). Target < 1.5x.
- run: ``gelrig run paper:shear`` piped (CPU s) against ``gelrig plan paper:shear``, and
  ``gelrig run --no-rehearse`` (one pass over the protocol, as the plan) against the same.
  Target < 1.6x.
- terminal: ``gelrig run paper:shear`` and ``paper:compression`` in a terminal (a pty made
  by ``script``) against the same run piped (CPU s). Target < 1.25x.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "gelrig.cli"]
#: One rehearsal in process after a first one: the rehearsal's own CPU (s) on stdout.
REHEARSAL = """
import sys, time
from gelrig.factory import build_twin
from gelrig.protocols.rehearsal import rehearse
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import load_protocol, paper_protocol
kind = sys.argv[1]
for _ in range(2):
    spec, protocol = load_rig(default_rig(kind)), load_protocol(paper_protocol(kind))
    c0 = time.process_time()
    twin = build_twin(spec)
    try:
        assert rehearse(twin, protocol).ok
    finally:
        twin.close()
    cpu = time.process_time() - c0
print(cpu)
"""


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}


def measure(argv: list[str], cwd: Path, tty: bool = False) -> tuple[float, float, str]:
    """(wall s, CPU s of the process and its children, stdout) of one process; it must
    succeed. ``tty``: under ``script``, so that the command's output is a terminal."""
    if tty:
        argv = ["script", "-qec", shlex.join(argv), "/dev/null"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=cwd, env=_env(), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert proc.stdout is not None
    out = proc.stdout.read()  # a pipe read as it comes, as a shell's pipe would be
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{argv} failed ({proc.returncode}): {out[-2000:]!r}")
    return wall, usage.ru_utime + usage.ru_stime, out.decode(errors="replace")


def rounds(commands: dict[str, Callable[[], float]], repeats: int) -> dict[str, list[float]]:
    """Each command once to warm up, then ``repeats`` rounds of all in turn."""
    for fn in commands.values():
        fn()
    out: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(repeats):
        for name, fn in commands.items():
            out[name].append(fn())
    return out


def report(title: str, unit: str, times: dict[str, list[float]], base: str,
           target: float | None = None) -> None:
    print(title)
    b = times[base]
    for name, runs in times.items():
        ratio = statistics.median(t / x for t, x in zip(runs, b, strict=True))
        mark = f"  (target < {target:g}x)" if target and name != base else ""
        print(f"  {name:44s} {statistics.median(runs):8.3f} {unit}  {ratio:6.2f}x{mark}")
    sys.stdout.flush()


def startup(repeats: int, tmp: Path) -> None:
    def wall(argv: list[str]) -> Callable[[], float]:
        return lambda: measure(argv, ROOT)[0]

    times = rounds({"python -c pass": wall([sys.executable, "-c", "pass"]),
                    "gelrig --help": wall([*CLI, "--help"]),
                    "gelrig plan --help": wall([*CLI, "plan", "--help"])}, repeats)
    report(f"start-up, whole processes, wall s, median of {repeats} rounds", "s", times,
           "python -c pass")


def plan(repeats: int, tmp: Path) -> None:
    def cpu(argv: list[str]) -> Callable[[], float]:
        return lambda: measure(argv, tmp)[1]

    def rehearsal() -> float:
        return float(measure([sys.executable, "-c", REHEARSAL, "compression"], tmp)[2])

    times = rounds({"rehearsal in process (paper:compression)": rehearsal,
                    "gelrig plan paper:compression": cpu([*CLI, "plan", "paper:compression"])},
                   repeats)
    report(f"plan, CPU s, median of {repeats} rounds", "s", times,
           "rehearsal in process (paper:compression)", 1.5)


def _run(kind: str, tmp: Path, tty: bool = False, *extra: str) -> Callable[[], float]:
    def fn() -> float:
        out = Path(tempfile.mkdtemp(dir=tmp))
        try:
            return measure([*CLI, "run", f"paper:{kind}", *extra, "--out", str(out / "r")],
                           tmp, tty)[1]
        finally:
            shutil.rmtree(out, ignore_errors=True)
    return fn


def run(repeats: int, tmp: Path) -> None:
    times = rounds({"gelrig plan paper:shear": lambda: measure([*CLI, "plan", "paper:shear"],
                                                               tmp)[1],
                    "gelrig run paper:shear": _run("shear", tmp),
                    "gelrig run --no-rehearse paper:shear": _run("shear", tmp, False,
                                                                 "--no-rehearse")}, repeats)
    report(f"run (piped), CPU s, median of {repeats} rounds", "s", times,
           "gelrig plan paper:shear", 1.6)


def terminal(repeats: int, tmp: Path) -> None:
    if shutil.which("script") is None:
        print("terminal: skipped (no `script` to make a pty)")
        return
    for kind in ("shear", "compression"):
        times = rounds({f"gelrig run paper:{kind} piped": _run(kind, tmp),
                        f"gelrig run paper:{kind} in a terminal": _run(kind, tmp, True)},
                       repeats)
        report(f"terminal, CPU s, median of {repeats} rounds", "s", times,
               f"gelrig run paper:{kind} piped", 1.25)


PARTS = {"startup": startup, "plan": plan, "run": run, "terminal": terminal}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", default=",".join(PARTS),
                        help=f"comma-separated parts of {', '.join(PARTS)}")
    args = parser.parse_args()
    parts = [p.strip() for p in args.only.split(",") if p.strip()]
    unknown = set(parts) - set(PARTS)
    if unknown:
        parser.error(f"--only: unknown {sorted(unknown)}; allowed {', '.join(PARTS)}")
    with tempfile.TemporaryDirectory() as tmp:
        for part in parts:
            PARTS[part](args.repeats, Path(tmp))


if __name__ == "__main__":
    main()
