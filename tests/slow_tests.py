"""Write tests/slow_tests.txt from a pytest ``--durations=0`` log: the fast tier's exclusions.

Usage: ``python tests/slow_tests.py LOG [--over SECONDS]``. A test whose setup, call or
teardown took longer than SECONDS (default 3) in that run is listed by its node id without
parameters, so all its parameter sets go to the slow tier together.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

_LINE = re.compile(r"^\s*([0-9.]+)s\s+(setup|call|teardown)\s+(\S+)")


def slow_ids(log: str, over: float) -> list[str]:
    """Node ids (parameters dropped) whose phase took longer than ``over`` seconds."""
    found = set()
    for line in log.splitlines():
        match = _LINE.match(line)
        if match and float(match.group(1)) > over:
            found.add(match.group(3).split("[")[0])
    return sorted(found)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--over", type=float, default=3.0, help="seconds (default 3)")
    args = parser.parse_args(argv)
    ids = slow_ids(args.log.read_text(encoding="utf-8", errors="replace"), args.over)
    target = Path(__file__).with_name("slow_tests.txt")
    header = f"# tests over {args.over:g} s in a full run (tests/slow_tests.py)\n"
    target.write_text(header + "".join(f"{i}\n" for i in ids), encoding="utf-8")
    print(f"{len(ids)} slow tests written to {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
