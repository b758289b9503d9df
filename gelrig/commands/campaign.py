"""``gelrig campaign CAMPAIGN.toml``: many simulated runs on Dask, one results table, a report.

Dask, pyarrow and the rig code are imported only when the command runs (``gelrig --help``
stays fast).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from pathlib import Path


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= 1024:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed: a whole number 1..1024")
    return value


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("campaign", help="run many simulated members of a protocol on Dask: "
                       "recovery of the hidden truth, interval coverage, protocol variants")
    p.add_argument("campaign", metavar="CAMPAIGN.toml", help="campaign file")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler (e.g. tcp://host:8786); default: a "
                        "LocalCluster on this machine")
    p.add_argument("--workers", type=_workers, default=None, metavar="N",
                   help="LocalCluster worker processes (default: the core count)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="results folder (default campaigns/<campaign file name>); a rerun "
                        "into the same folder resumes, skipping members already done")
    p.add_argument("--keep-runs", action="store_true",
                   help="keep each member's run directory in OUT/runs/<member id>")
    p.add_argument("--retry-failed", action="store_true",
                   help="run again the members stored as failed")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--sample", default=None, metavar="NAME",
                   help="the sample's name in each member's run (its sizes the protocol's)")
    from gelrig.commands.run import run_info_args

    run_info_args(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from gelrig.campaign.engine import run_members
    from gelrig.campaign.report import summary_lines, write_campaign_report
    from gelrig.campaign.spec import load_campaign
    from gelrig.campaign.store import RESULTS, ResultStore

    out = Path(args.out) if args.out else Path("campaigns") / Path(args.campaign).stem
    store = ResultStore(out, warn=lambda line: print(f"gelrig: warning: {line}",
                                                     file=sys.stderr))  # --out checked first
    from gelrig.protocols.runinfo import run_info
    from gelrig.protocols.sample import check_sample_name

    info = run_info(args.operator, args.note, args.tag)
    spec = load_campaign(args.campaign)
    members = list(spec.members)
    meta = info.table()
    if args.sample is not None:
        meta["sample"] = check_sample_name(args.sample)
    if any(meta.values()):
        members = [dataclasses.replace(m, run_meta=meta) for m in members]
    if args.keep_runs:
        runs = (out / "runs").resolve()
        members = [dataclasses.replace(m, keep_dir=str(runs / m.member_id)) for m in members]
    grids = ", ".join(f"{k} x{len(v)}" for k, v in {**spec.truth_grid, **spec.param_grid}
                      .items() if len(v) > 1) or "no grid"
    print(f"campaign {spec.name!r}: {len(members)} member(s) of {spec.protocol_ref} "
          f"({grids}; {spec.replicates} seed(s)); results in {out.resolve()}")
    stats = run_members(members, store, workers=args.workers, scheduler=args.scheduler,
                        retry_failed=args.retry_failed, progress=not args.no_progress)
    if stats.skipped:
        print(f"resumed: {stats.skipped} member(s) already done were skipped")
    if stats.submitted:
        rate = stats.submitted / stats.wall_s * 60 if stats.wall_s > 0 else float("nan")
        print(f"ran {stats.submitted} member(s) on {stats.where} in {stats.wall_s:.1f} s "
              f"({rate:.1f} members/min), {stats.failed} failed")
    table = store.consolidate(m.member_id for m in members)
    rows = table.to_pylist()
    print("\n".join(summary_lines(rows)))
    print(f"results: {(out / RESULTS).resolve()}")
    try:
        page = write_campaign_report(out / "report", f"gelrig campaign: {spec.name}", rows)
    except Exception as exc:  # the results are stored: a report that fails must not hide them
        if args.debug:
            raise
        logging.getLogger(__name__).debug("report failed", exc_info=True)
        print(f"gelrig: the report could not be written ({type(exc).__name__}: "
              f"{' '.join(str(exc).split())[:200]}); the results table is complete",
              file=sys.stderr)
        return 1
    print(f"report: {page.resolve()}")
    failed = sum(r.get("status") == "failed" for r in rows)
    if failed:
        print(f"gelrig: warning: {failed} member(s) failed; their errors are in the table "
              "and the report", file=sys.stderr)
    return 0
