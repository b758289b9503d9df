"""Campaign throughput on Dask: members per minute with 1 and 2 local workers, the scaling
efficiency, and Dask's overhead per member against the same members run in one process.

Run: python benchmarks/bench_campaign.py [--members 8] [--repeats 3]

The members are the tests' tiny compression campaign (the paper protocol with a 60 s hold at
100 Hz: about 2 s a member) over ``--members`` noise seeds. The baseline, measured in the same
run, calls :func:`gelrig.campaign.member.run_member` on each member in this process, one after
the other (warm: one member is run first, untimed). A Dask run is a LocalCluster of process
workers; its start (cluster up, member code imported on every worker) is reported apart and
left out of the members' wall time. Medians over ``--repeats``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gelrig.campaign.engine import run_members  # noqa: E402
from gelrig.campaign.member import run_member  # noqa: E402
from gelrig.campaign.spec import MemberSpec, parse_campaign  # noqa: E402
from gelrig.campaign.store import ResultStore  # noqa: E402

CAMPAIGN = {
    "campaign": {"name": "bench", "protocol": "paper:compression", "replicates": 1},
    "params": {"step[1].hold": "60 s", "step[1].rate": "100 Hz"},
}


def members(n: int, first_seed: int) -> list[MemberSpec]:
    table = {**CAMPAIGN, "campaign": {**CAMPAIGN["campaign"], "replicates": n,
                                      "first_seed": first_seed}}
    return list(parse_campaign(table, "bench").members)


def serial(batch: list[MemberSpec]) -> tuple[float, float]:
    """(wall s, median member wall s) of the members run one after the other here."""
    t0 = time.perf_counter()
    walls = []
    for m in batch:
        record = run_member(m)
        if record["status"] != "ok":
            raise SystemExit(f"member {m.member_id} failed")
        walls.append(record["wall_s"])
    return time.perf_counter() - t0, statistics.median(walls)


def pool(batch: list[MemberSpec], processes: int) -> float:
    """Wall s of the members on a plain process pool (warm): what this machine gives two
    processes at all, the ceiling for the workers' scaling."""
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(processes) as executor:
        list(executor.map(run_member, members(processes, 20_000)))  # warm every process
        t0 = time.perf_counter()
        records = list(executor.map(run_member, batch))
        wall = time.perf_counter() - t0
    if any(r["status"] != "ok" for r in records):
        raise SystemExit("a member failed")
    return wall


def dask(batch: list[MemberSpec], workers: int) -> tuple[float, float, float, float]:
    """(members' wall s, startup s, sum and median of the members' own wall s) on a
    LocalCluster of ``workers`` processes."""
    records: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        stats = run_members(batch, ResultStore(Path(tmp)), workers=workers, progress=False,
                            on_record=records.append)
    if stats.failed:
        raise SystemExit(f"{stats.failed} member(s) failed")
    walls = [r["wall_s"] for r in records]
    return stats.wall_s - stats.startup_s, stats.startup_s, sum(walls), statistics.median(walls)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    n = args.members
    run_member(members(1, 10_000)[0])  # warm this process
    base, one, two, start1, start2, own1, plain2 = [], [], [], [], [], [], []
    typical_here, typical_worker = [], []
    for r in range(args.repeats):
        batch = members(n, 1 + r * n)  # fresh seeds: nothing is skipped
        wall, typical = serial(batch)
        base.append(wall)
        typical_here.append(typical)
        wall, start, own, typical = dask(batch, 1)
        typical_worker.append(typical)
        one.append(wall)
        start1.append(start)
        own1.append(own)
        wall, start, _, _ = dask(batch, 2)
        two.append(wall)
        start2.append(start)
        plain2.append(pool(batch, 2))
    b, w1, w2 = (statistics.median(x) for x in (base, one, two))
    rate = {k: n / v * 60 for k, v in (("base", b), ("1", w1), ("2", w2))}
    print(f"{n} members (paper compression, 60 s hold at 100 Hz), medians of {args.repeats}")
    print(f"one process (baseline): {b:.2f} s, {rate['base']:.1f} members/min")
    print(f"Dask, 1 worker:  {w1:.2f} s, {rate['1']:.1f} members/min "
          f"(ratio to the baseline {rate['1'] / rate['base']:.2f}); "
          f"cluster start {statistics.median(start1):.2f} s")
    print(f"Dask, 2 workers: {w2:.2f} s, {rate['2']:.1f} members/min "
          f"(ratio to the baseline {rate['2'] / rate['base']:.2f}); "
          f"cluster start {statistics.median(start2):.2f} s")
    p2 = statistics.median(plain2)
    print(f"scaling efficiency 1 -> 2 workers: {rate['2'] / (2 * rate['1']) * 100:.0f} %; "
          f"a plain pool of 2 processes (warm, no Dask): {n / p2 * 60:.1f} members/min, "
          f"{n / p2 * 60 / (2 * rate['base']) * 100:.0f} % of twice the baseline (the "
          f"machine's ceiling); Dask's 2 workers reach {w2 and p2 / w2 * 100:.0f} % of it")
    o1 = statistics.median(own1)
    print(f"Dask overhead per member (1 worker against one process): "
          f"{(w1 - b) / n * 1e3:+.0f} ms ({(w1 - b) / b * 100:+.1f} %); of which the members "
          f"ran {(o1 - b) / n * 1e3:+.0f} ms slower in the worker process and "
          f"{(w1 - o1) / n * 1e3:.0f} ms went to scheduling, transfer and storing")
    th, tw = statistics.median(typical_here), statistics.median(typical_worker)
    print(f"a typical member (median): {th * 1e3:.0f} ms in this process, {tw * 1e3:.0f} ms in "
          f"a worker ({(tw - th) * 1e3:+.0f} ms)")


if __name__ == "__main__":
    main()
