"""Every benchmark starts as ``make bench`` runs it: its own process, from another directory
(issue 31 item 6: one failed with ModuleNotFoundError and stopped ``make bench``)."""

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = sorted((Path(__file__).resolve().parents[2] / "benchmarks").glob("bench_*.py"))


@pytest.mark.slow
@pytest.mark.parametrize("script", BENCHMARKS, ids=lambda p: p.name)
def test_each_benchmark_imports_and_parses_its_options_standalone(script: Path,
                                                                  tmp_path: Path) -> None:
    out = subprocess.run([sys.executable, str(script), "--help"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith("usage:")


def test_the_benchmarks_are_found() -> None:
    assert len(BENCHMARKS) >= 20
