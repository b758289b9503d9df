"""The chaos soak (benchmarks/bench_chaos_soak.py) runs and finds nothing, for three runs.

One run each of a wire fault (the link cut mid-run), a process fault (gelrig SIGKILLed, then
``gelrig resume``) and a disk fault (the run's tmpfs filled, then resume; a control run
where no tmpfs can be mounted), through the same code as the 30-minute soak, so that it
cannot rot: every check from outside (export vs samples seen flushed, run.json vs the twin
read directly, the load left on the rig, exit codes, tracebacks) must come out clean.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(sys.platform == "win32", reason="needs SIGKILL, SIGSTOP")]


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "bench_chaos_soak", ROOT / "benchmarks" / "bench_chaos_soak.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_three_faulted_runs_lose_nothing_and_leave_the_rigs_safe(tmp_path: Path) -> None:
    pytest.importorskip("pylablib.devices.Thorlabs.kinesis", exc_type=ImportError)
    bench = _bench()
    lines: list[str] = []
    # seed 6 draws: compression gelrig_kill, shear link_drop, compression disk_full
    episodes = bench.soak(30.0, 6, tmp_path, log=lines.append,
                          faults=("disk_full", "gelrig_kill", "link_drop"), runs=3)
    drawn = [(e.plan.rig, e.plan.fault) for e in episodes]
    disk = "disk_full" if bench.can_mount() else "none"
    assert drawn == [("compression", "gelrig_kill"), ("shear", "link_drop"),
                     ("compression", disk)], lines
    assert [e.bad for e in episodes] == [[], [], []], "\n".join(lines)
    killed = episodes[0]
    assert killed.exits == [-9, 0] and killed.status == "completed"  # resumed to the end
    assert all(e.observed > 0 for e in episodes)  # the outside reader saw samples
    assert not any(e.loaded for e in episodes)
    table = bench.report(episodes, 30.0, 6, 60.0)
    assert re.search(r"^  data lost \(samples\) +0$", table, re.M), table
    assert re.search(r"^  runs +3 \(", table, re.M), table
