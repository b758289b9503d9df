"""The catalog of runs on hand-written run folders: what it indexes, how it catches up with
the folders, and that a locked or damaged index never raises (ADR 0370)."""

import json
import os
import sqlite3
import subprocess
import sys
import time

import pytest

from gelrig.instrument.core.catalog import (
    CATALOG_NAME,
    catalog_entries,
    index_run,
    live_status,
    parse_when,
    select_entries,
    step_results,
)
from gelrig.instrument.core.errors import ConfigError

FIT = {"G_e": 7000.0, "relax": [{"G": 600.0, "tau": 5.0}], "terms_requested": 1,
       "resolved": True, "stderr": {"G_e": 10.0, "G_1": 2.0, "tau_1": 0.1}}
UNRESOLVED = {"G_e": 1.0, "relax": [{"G": 2.0, "tau": 3.0}], "terms_requested": 2,
              "resolved": False, "stderr": {}}


def make_run(root, name, sample="gel-A1", status="completed", started="2026-11-25T08:00:00+0000",
             **extra):
    folder = root / name
    folder.mkdir(parents=True)
    meta = {"sample": {"name": sample, "diameter": 0.012}, "operator": "ada", "note": "n",
            "tags": ["week48"], "protocol": {"protocol": {"name": "hold", "rig": "compression"}},
            "rig": {"rig": {"kind": "compression"}}, "clock": "virtual", "status": status,
            "started_wall": started, "finished_wall": "", "steps": [
                {"index": 1, "name": "hold", "kind": "ramp_hold", "status": "completed",
                 "file": "steps/01_hold.h5", "results": {
                     "depth_m": 1e-3, "first_touch_ramp_m": 6e-3,
                     "first_touch_ramp_se_m": 1e-6, "fits": [FIT, UNRESOLVED]}}],
            **extra}
    (folder / "run.json").write_text(json.dumps(meta))
    return folder


def test_step_results_hold_values_intervals_and_units():
    rows = {r["quantity"]: r for r in step_results(
        {"results": {"depth_m": 1e-3, "first_touch_ramp_m": 6e-3,
                     "first_touch_ramp_se_m": 1e-6, "held_s": 30, "fits": [FIT, UNRESOLVED]}})}
    assert rows["depth_m"]["unit"] == "m" and rows["depth_m"]["lo"] is None
    assert rows["first_touch_ramp_m"]["stderr"] == 1e-6
    assert rows["1-term G_e"]["lo"] == pytest.approx(7000 - 1.96 * 10, abs=0.01)
    assert rows["1-term tau_1"]["unit"] == "s" and rows["1-term G_1"]["unit"] == "Pa"
    assert not any(k.startswith("2-term") for k in rows)  # an unresolved fit gives no values
    assert "first_touch_ramp_se_m" not in rows and rows["held_s"]["unit"] == "s"


def test_index_then_list_then_catch_up_with_the_folders(tmp_path):
    a = make_run(tmp_path, "a")
    assert index_run(a) == ""
    with sqlite3.connect(tmp_path / CATALOG_NAME) as con:
        assert con.execute("SELECT name, sample, operator FROM runs").fetchall() == [
            ("a", "gel-A1", "ada")]
    make_run(tmp_path, "b", sample="gel-B2", started="2026-11-26T08:00:00+0000")
    entries = catalog_entries(tmp_path)  # b found although nobody indexed it
    assert [e["name"] for e in entries] == ["a", "b"]
    assert entries[1]["sample"] == "gel-B2"
    assert entries[0]["steps"][0]["results"][0]["quantity"] == "depth_m"
    meta = json.loads((a / "run.json").read_text())
    meta["operator"] = "bo"
    time.sleep(0.01)
    (a / "run.json").write_text(json.dumps(meta, indent=1))  # a changed: read again
    (tmp_path / "b" / "run.json").unlink()  # b gone
    entries = catalog_entries(tmp_path)
    assert [(e["name"], e["operator"]) for e in entries] == [("a", "bo")]


def test_a_damaged_index_is_rebuilt_with_one_warning(tmp_path):
    make_run(tmp_path, "a")
    (tmp_path / CATALOG_NAME).write_bytes(b"garbage " * 500)
    assert "not updated" in index_run(tmp_path / "a")  # never raises
    said = []
    assert [e["name"] for e in catalog_entries(tmp_path, said.append)] == ["a"]
    assert len(said) == 1 and "rebuilt" in said[0]
    assert catalog_entries(tmp_path, said.append) and len(said) == 1  # sound again


def test_a_locked_index_is_not_waited_for(tmp_path):
    a = make_run(tmp_path, "a")
    assert index_run(a) == ""
    holder = sqlite3.connect(tmp_path / CATALOG_NAME, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        started = time.monotonic()
        problem = index_run(a)
        assert time.monotonic() - started < 0.5
        assert "locked" in problem and "the run goes on" in problem
    finally:
        holder.execute("ROLLBACK")
        holder.close()


def test_a_run_whose_process_is_gone_is_interrupted(tmp_path):
    folder = make_run(tmp_path, "a", status="running")
    assert live_status(folder, "running") == ("interrupted", None)  # no run.lock
    (folder / "run.lock").write_text(f"process {os.getpid()} (pytest) since now")
    assert live_status(folder, "running") == ("running", os.getpid())
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (folder / "run.lock").write_text(f"process {dead.pid} (gelrig run) since now")
    assert live_status(folder, "running") == ("interrupted", dead.pid)
    assert live_status(folder, "failed") == ("failed", None)


def test_filters_select_runs(tmp_path):
    entries = [{"sample": "gel-A1", "operator": "ada", "protocol": "hold", "status": "completed",
                "tags": ["week48"], "started": "2026-11-25T08:00:00+0000"},
               {"sample": "gel-B2", "operator": "bo", "protocol": "ladder", "status": "failed",
                "tags": [], "started": "2026-11-27T08:00:00+0000"}]
    assert len(select_entries(entries, sample="gel-a1")) == 1
    assert len(select_entries(entries, sample=["gel-A1", "gel-B2"])) == 2
    assert len(select_entries(entries, protocol="h*")) == 1
    assert len(select_entries(entries, tag="week48", status="completed")) == 1
    assert len(select_entries(entries, since="2026-11-26")) == 1
    assert len(select_entries(entries, until="2026-11-25")) == 1  # the whole day
    with pytest.raises(ConfigError, match="since"):
        parse_when("last tuesday", "since")
    with pytest.raises(ConfigError, match="allowed filters"):
        select_entries(entries, colour="red")
