"""A campaign killed (SIGKILL, the whole process group) mid-way resumes: the members already
stored are skipped, the rest run, and the table holds every member once."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from gelrig.campaign.spec import load_campaign
from tests.gelrig.campaign import tiny

ROOT = Path(__file__).resolve().parents[3]
#: Wall seconds the first run may take to store its first members (bounded wait).
FIRST_PARTS_WITHIN = 120.0


def _campaign(args: list[str]) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    return subprocess.Popen([sys.executable, "-m", "gelrig.cli", "campaign", *args,
                             "--no-progress"], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)


@pytest.mark.slow
def test_a_killed_campaign_resumes_skipping_the_members_done(tmp_path):
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=4)
    ids = {m.member_id for m in load_campaign(path).members}
    out = tmp_path / "out"
    args = [str(path), "--out", str(out), "--workers", "1"]
    first = _campaign(args)
    parts = out / "parts"
    deadline = time.monotonic() + FIRST_PARTS_WITHIN
    try:
        while not list(parts.glob("*.parquet")):
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < deadline, "no member stored in time"
            time.sleep(0.05)
    finally:
        os.killpg(first.pid, signal.SIGKILL)  # the CLI and its Dask workers, at once
        first.communicate(timeout=30)
    before = {p.stem: p.stat().st_mtime_ns for p in parts.glob("*.parquet")}
    assert 1 <= len(before) < len(ids)
    assert not (out / "results.parquet").exists()

    second = _campaign(args)
    stdout, stderr = second.communicate(timeout=300)
    assert second.returncode == 0, stderr
    skipped = re.search(r"resumed: (\d+) member\(s\) already done were skipped", stdout)
    assert skipped and int(skipped.group(1)) == len(before), stdout
    ran = re.search(r"ran (\d+) member\(s\)", stdout)
    assert ran and int(ran.group(1)) == len(ids) - len(before), stdout
    for member_id, mtime in before.items():  # not run again
        assert (parts / f"{member_id}.parquet").stat().st_mtime_ns == mtime
    table = pq.read_table(out / "results.parquet").to_pylist()
    assert sorted(r["member_id"] for r in table) == sorted(ids)  # complete, no duplicates
    assert all(r["status"] == "ok" for r in table), [r["error"] for r in table]
    assert (out / "report" / "report.html").exists()
