"""Damaged Parquet parts of a campaign: one line each, moved aside, their members run again."""

from __future__ import annotations

import os

import pyarrow.parquet as pq

from gelrig.campaign.engine import run_members
from gelrig.campaign.spec import load_campaign
from gelrig.campaign.store import ResultStore
from gelrig.cli import main
from tests.gelrig.campaign import tiny


def _records(store: ResultStore, *ids: str) -> None:
    for i, member_id in enumerate(ids):
        store.write({"member_id": member_id, "index": i, "status": "ok", "wall_s": 1.0})


def test_damaged_parts_are_set_aside_and_their_members_are_not_finished(tmp_path):
    lines: list[str] = []
    store = ResultStore(tmp_path / "out", warn=lines.append)
    _records(store, "good", "cut", "garbage", "other", "fifo")
    parts = store.parts
    os.truncate(parts / "cut.parquet", (parts / "cut.parquet").stat().st_size // 2)
    (parts / "garbage.parquet").write_bytes(b"PAR1" + os.urandom(200) + b"PAR1")
    (parts / "other.parquet").write_bytes((parts / "good.parquet").read_bytes())  # wrong id
    (parts / "fifo.parquet").unlink()
    os.mkfifo(parts / "fifo.parquet")
    assert store.finished() == {"good"}
    assert len(lines) == 4 and all("\n" not in line for line in lines)
    by_member = {line.split(": ")[0].rsplit("/", 1)[-1]: line for line in lines}
    assert set(by_member) == {"cut.parquet", "garbage.parquet", "other.parquet",
                              "fifo.parquet"}
    for name, line in by_member.items():
        assert f"moved to {parts / 'damaged' / name}" in line
        assert f"member {name.removesuffix('.parquet')} runs again" in line
    assert "not a regular file" in by_member["fifo.parquet"]
    assert "not member other's one" in by_member["other.parquet"]
    assert sorted(p.name for p in (parts / "damaged").iterdir()) == sorted(by_member)
    assert [r["member_id"] for r in store.read(["good", "cut"])] == ["good"]
    assert store.consolidate(["good", "cut"]).column("member_id").to_pylist() == ["good"]
    # a second damaged copy of the same member does not overwrite the first one set aside
    (parts / "cut.parquet").write_bytes(b"not parquet")
    assert store.finished() == {"good"}
    assert (parts / "damaged" / "cut.1.parquet").exists()


def test_a_campaign_reruns_the_members_of_damaged_parts(tmp_path, capsys):
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=2)
    spec = load_campaign(path)
    out = tmp_path / "out"
    run_members(spec.members, ResultStore(out), workers=1, processes=False, progress=False)
    damaged = out / "parts" / f"{spec.members[0].member_id}.parquet"
    os.truncate(damaged, damaged.stat().st_size - 20)  # a torn copy
    assert main(["campaign", str(path), "--out", str(out), "--workers", "1",
                 "--no-progress"]) == 0
    captured = capsys.readouterr()
    warnings = [line for line in captured.err.splitlines() if "damaged part" in line]
    assert len(warnings) == 1 and "Traceback" not in captured.err
    assert warnings[0].startswith(f"gelrig: warning: {damaged}: damaged part, not read (")
    assert f"member {spec.members[0].member_id} runs again" in warnings[0]
    assert "resumed: 1 member(s) already done were skipped" in captured.out
    assert "ran 1 member(s)" in captured.out
    table = pq.read_table(out / "results.parquet").to_pylist()
    assert sorted(r["member_id"] for r in table) == sorted(m.member_id for m in spec.members)
    assert pq.read_table(damaged).num_rows == 1  # stored again, whole
