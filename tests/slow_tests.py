"""Write tests/slow_tests.txt from a full run's timings: the fast tier's exclusions.

Usage: ``python tests/slow_tests.py LOG [--over SECONDS]``, LOG a pytest ``--durations=0``
log or a ``--junitxml`` report. A test whose setup, call or teardown (in a JUnit report:
the three together) took longer than SECONDS (default 1) in that run is listed by its node
id without parameters, so all its parameter sets go to the slow tier together. ``--merge``
keeps the tests already listed: run it on a report of the fast tier itself to list the
tests that inherited a module-wide set-up from a test the list took out.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from xml.etree import ElementTree

_LINE = re.compile(r"^\s*([0-9.]+)s\s+(setup|call|teardown)\s+(\S+)")


def slow_ids(log: str, over: float) -> list[str]:
    """Node ids (parameters dropped) whose phase took longer than ``over`` seconds."""
    found = set()
    for line in log.splitlines():
        match = _LINE.match(line)
        if match and float(match.group(1)) > over:
            found.add(match.group(3).split("[")[0])
    return sorted(found)


def slow_ids_junit(report: str, over: float) -> list[str]:
    """Node ids (parameters dropped) from a JUnit XML report whose test took longer than
    ``over`` seconds."""
    found = set()
    for case in ElementTree.fromstring(report).iter("testcase"):
        if float(case.get("time", "0")) > over:
            module = (case.get("classname") or "").replace(".", "/") + ".py"
            found.add(f"{module}::{(case.get('name') or '').split('[')[0]}")
    return sorted(found)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--over", type=float, default=1.0, help="seconds (default 1)")
    parser.add_argument("--merge", action="store_true", help="keep the tests already listed")
    args = parser.parse_args(argv)
    text = args.log.read_text(encoding="utf-8", errors="replace")
    junit = text.lstrip().startswith("<?xml") or text.lstrip().startswith("<testsuite")
    ids = slow_ids_junit(text, args.over) if junit else slow_ids(text, args.over)
    target = Path(__file__).with_name("slow_tests.txt")
    if args.merge and target.exists():
        lines = (line.strip() for line in target.read_text(encoding="utf-8").splitlines())
        kept = {line for line in lines if line and not line.startswith("#")}
        listed_modules = {line.split("::")[0] for line in kept}
        # a slow test in a module the list already cut inherited its module-wide set-up:
        # the whole module goes (else the set-up moves on to its next test)
        ids = sorted(kept | {i.split("::")[0] if i.split("::")[0] in listed_modules else i
                             for i in ids})
    header = f"# tests over {args.over:g} s in a full run (tests/slow_tests.py)\n"
    target.write_text(header + "".join(f"{i}\n" for i in ids), encoding="utf-8")
    print(f"{len(ids)} slow tests written to {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
