"""Memory per run in one process stays flat (issue 32): runs through the scripting API keep
nothing of earlier runs, and what a run freed goes back to the system as it ends."""

from __future__ import annotations

import gc
import tracemalloc
from itertools import pairwise

import pytest

import gelrig
from gelrig.instrument.core import motion, stage_path
from gelrig.protocols import host
from gelrig.simulators.kdc101 import device

PROTOCOL = """
[protocol]
name = "short"
rig = "compression"

[[step]]
kind = "compression_contact_search"
start = "3 mm"
confirm = 0
tare_time = "0.5 s"

[[step]]
kind = "ramp_hold"
diameter = "18.63 mm"
hold = "10 s"
rate = "100 Hz"
terms = 1
strain_rate = "0.02 /s"
"""


def test_runs_in_one_process_keep_nothing_of_earlier_runs(tmp_path, monkeypatch):
    # bounded histories fill in one run, so what grows after is a leak: the simulator's log,
    # the simulated stage's path (a day of lab time: about 35 phases a run here, 1-10 kB),
    # and the KDC101 driver's stage path (up to 4096 reports, 256 commands: ~1 MB when full)
    monkeypatch.setattr(device, "KEPT_MESSAGES", 100)
    monkeypatch.setattr(motion, "HISTORY", 60.0)
    monkeypatch.setattr(stage_path, "KEEP_REPORTS", 64)
    monkeypatch.setattr(stage_path, "KEEP_SEGMENTS", 16)
    released = []
    real = host.release_freed_memory
    monkeypatch.setattr(host, "release_freed_memory", lambda: (released.append(1), real()))
    path = tmp_path / "p.toml"
    path.write_text(PROTOCOL)
    traced = []
    tracemalloc.start()
    try:
        with gelrig.open_rig("compression") as rig:
            for i in range(7):
                assert rig.run(path, out=tmp_path / f"run{i}").ok
                gc.collect()
                traced.append(tracemalloc.get_traced_memory()[0])
    finally:
        tracemalloc.stop()
    assert len(released) == 7  # once as each run ended
    per_run = (traced[-1] - traced[2]) / (len(traced) - 3)
    assert per_run < 20_000, [f"{(b - a) / 1e3:+.0f} kB" for a, b in pairwise(traced)]


@pytest.mark.parametrize("available", [True, False])
def test_release_freed_memory_works_with_and_without_glibc(monkeypatch, available):
    from gelrig.instrument.core import memory

    calls = []
    monkeypatch.setattr(memory, "_malloc_trim",
                        lambda: (lambda pad: calls.append(pad) or 1) if available else None)
    memory.release_freed_memory()
    assert calls == ([0] if available else [])
