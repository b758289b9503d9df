"""A campaign on a real Dask LocalCluster: every member stored, failures recorded, none lost."""

from __future__ import annotations

import math

from gelrig.campaign.engine import run_members
from gelrig.campaign.report import coverage, summary_lines, write_campaign_report
from gelrig.campaign.spec import load_campaign
from gelrig.campaign.store import ResultStore
from tests.gelrig.campaign import tiny


def test_four_members_on_a_local_cluster_with_a_failing_truth(tmp_path):
    # two seeds x a sphere where the paper's stage finds it, and one beyond the stage's travel
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=2,
                      simulator='first_touch = ["6.2 mm", "20 mm"]')
    spec = load_campaign(path)
    store = ResultStore(tmp_path / "out")
    seen = []
    stats = run_members(spec.members, store, workers=2, processes=False, progress=False,
                        on_record=seen.append)
    assert stats.submitted == 4 and stats.skipped == 0 and len(seen) == 4
    rows = {r["member_id"]: r for r in store.consolidate(m.member_id for m in spec.members)
            .to_pylist()}
    assert set(rows) == {m.member_id for m in spec.members}
    for member in spec.members:
        row = rows[member.member_id]
        assert row["seed"] == member.seed
        if member.truth["first_touch"] == "20 mm":
            assert row["status"] == "failed" and row["state"] == "failed"
            assert "travel limits" in row["error"]
        else:
            assert row["status"] == "ok", row["error"]
            assert math.isclose(row["truth.G_e"], 7146.0)
            assert row["lo.G_e"] < row["fit.G_e"] < row["hi.G_e"]
            assert row["held_s"] > 0 and row["wall_s"] > 0
    assert stats.failed == 2
    # the seeds differ: their fits are not copies
    ok = [r for r in rows.values() if r["status"] == "ok"]
    assert ok[0]["fit.G_e"] != ok[1]["fit.G_e"]
    # a rerun skips them all
    again = run_members(spec.members, store, workers=1, processes=False, progress=False)
    assert again.submitted == 0 and again.skipped == 4
    page = write_campaign_report(tmp_path / "out" / "report", "tiny", list(rows.values()))
    html = page.read_text()
    assert "coverage.png" in html and "bias_spread.png" in html and "travel limits" in html
    assert (page.parent / "variants.csv").exists()
    # a 60 s hold resolves no term: its members are no result for coverage and bias
    assert [r["resolved"] for r in ok] == [False, False]
    cov = coverage(list(rows.values()), "G_e")
    assert (cov.n, cov.unresolved) == (0, 2)
    lines = summary_lines(list(rows.values()))
    assert lines[0] == ("4 member(s): 2 ok, 0 incomplete, 2 failed, 2 ok but not resolved "
                        "(left out of bias and coverage)")
    assert "  G_e          no resolved member (2 not resolved)" in lines


def test_members_run_on_an_existing_scheduler(tmp_path):
    from distributed import LocalCluster

    spec = load_campaign(tiny.write(tmp_path, tiny.COMPRESSION, replicates=2))
    store = ResultStore(tmp_path / "out")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address="127.0.0.1:0") as cluster:
        stats = run_members(spec.members, store, scheduler=cluster.scheduler_address,
                            progress=False)
    assert stats.where == cluster.scheduler_address and stats.submitted == 2
    rows = store.consolidate(m.member_id for m in spec.members).to_pylist()
    assert [r["status"] for r in rows] == ["ok", "ok"], [r["error"] for r in rows]
