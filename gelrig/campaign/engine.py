"""Runs a campaign's members on Dask distributed: a LocalCluster of N worker processes by
default, or an existing cluster (``--scheduler ADDRESS``).

Members are submitted at once and gathered as they complete; each finished member is stored
at once (:class:`~gelrig.campaign.store.ResultStore`), so a killed campaign resumes where it
stopped. A member that fails (its run, its analysis, even its worker) is a record with the
error; the campaign goes on. A rich progress bar shows members done and the ETA.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from gelrig.campaign.member import run_member
from gelrig.campaign.spec import MemberSpec
from gelrig.campaign.store import ResultStore
from gelrig.instrument.core.errors import ConfigError

#: A member is mostly Python on a few threads: every wake-up of a worker's housekeeping takes
#: the GIL from it. The statistical profiler (every 10 ms), the event-loop health tick (20 ms)
#: and the system monitor (500 ms) are turned off or slowed on the LocalCluster's workers (the
#: Nanny hands the settings on to the worker processes; ADR 0190).
QUIET_WORKERS = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.system-monitor.gil.enabled": False,
}
#: Wall seconds to wait for a scheduler given with ``--scheduler``.
CONNECT_TIMEOUT = 10.0


@dataclass
class EngineStats:
    """What a campaign run did: members run now, skipped (stored before), failed, wall s."""

    submitted: int = 0
    skipped: int = 0
    failed: int = 0
    wall_s: float = 0.0
    #: Wall s to start (or reach) the cluster and load the member code on every worker.
    startup_s: float = 0.0
    workers: int = 0
    where: str = ""


def default_workers() -> int:
    """The core count this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int, processes: bool = True
                ) -> Iterator[Any]:
    """A connected ``distributed.Client``: to ``scheduler``, or to a new LocalCluster of
    ``workers`` single-threaded workers (processes unless ``processes=False``)."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError("--scheduler", scheduler, f"cannot connect to a Dask scheduler "
                              f"there ({' '.join(str(exc).split())[:200]}); give its address, "
                              "e.g. tcp://host:8786") from None
        with client:
            yield client
        return
    # The scheduler's HTTP server starts even without a dashboard, on 8787 by default: a free
    # port instead, so that two campaigns (or a campaign and a test) can run side by side.
    with dask.config.set(QUIET_WORKERS):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                               dashboard_address="127.0.0.1:0",
                               silence_logs=logging.CRITICAL)
    with cluster, Client(cluster) as client:
        yield client


#: What a member imports: loaded on every worker before the members start.
MEMBER_MODULES = ("matplotlib.pyplot", "scipy.optimize", "nidaqmx", "h5py", "gelrig.factory",
                  "gelrig.analyze_run", "gelrig.instrument.analysis.model_fit",
                  "gelrig.protocols.host")


def _load_member_code() -> None:
    """Import what a member runs, once per worker (counted in the startup, not per member)."""
    import importlib

    import matplotlib

    matplotlib.use("Agg")  # a worker draws the member's report figures off screen
    for name in MEMBER_MODULES:
        importlib.import_module(name)


def _lost(member: MemberSpec, exc: BaseException) -> dict[str, Any]:
    """The record of a member whose task itself failed (e.g. its worker died)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return {"member_id": member.member_id, "index": member.index, "seed": member.seed,
            "status": "failed", "state": "", "error": f"{type(exc).__name__}: {text}"[:500],
            "wall_s": float("nan")}


def run_members(
    members: Sequence[MemberSpec],
    store: ResultStore,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    processes: bool = True,
    retry_failed: bool = False,
    progress: bool = True,
    on_record: Callable[[dict[str, Any]], object] | None = None,
) -> EngineStats:
    """Run every member not yet stored, storing each as it completes."""
    done = store.finished(retry_failed)
    todo = [m for m in members if m.member_id not in done]
    stats = EngineStats(skipped=len(members) - len(todo))
    if not todo:
        return stats
    from distributed import as_completed

    start = time.perf_counter()
    n = workers or default_workers()
    with dask_client(scheduler, n, processes) as client, _bar(progress, len(members),
                                                              stats.skipped) as advance:
        client.run(_load_member_code)
        stats.startup_s = time.perf_counter() - start
        stats.workers = len(client.scheduler_info().get("workers", {})) or n
        stats.where = scheduler or f"LocalCluster, {n} worker(s)"
        futures = {client.submit(run_member, m, key=f"gelrig-member-{m.member_id}",
                                 pure=False): m for m in todo}
        stats.submitted = len(futures)
        for future in as_completed(futures):
            member = futures[future]
            try:
                record = future.result()
            except Exception as exc:
                record = _lost(member, exc)
            store.write(record)
            stats.failed += record.get("status") == "failed"
            future.release()
            advance(record)
            if on_record is not None:
                on_record(record)
    stats.wall_s = time.perf_counter() - start
    return stats


@contextlib.contextmanager
def _bar(show: bool, total: int, skipped: int
         ) -> Iterator[Callable[[dict[str, Any]], None]]:
    """A progress bar of members done (of all, the skipped ones counted) with the ETA."""
    if not show:
        yield lambda record: None
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = (TextColumn("members"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[failed]} failed"), TimeElapsedColumn(),
               TextColumn("ETA"), TimeRemainingColumn())
    with Progress(*columns, transient=False) as bar:
        task = bar.add_task("members", total=total, completed=skipped, failed=0)
        failed = 0

        def advance(record: dict[str, Any]) -> None:
            nonlocal failed
            failed += record.get("status") == "failed"
            bar.update(task, advance=1, failed=failed)

        yield advance
