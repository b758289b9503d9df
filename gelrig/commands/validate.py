"""``gelrig validate``: re-measure the README's quantitative claims with the built-in suite of
campaigns (``examples/campaigns/validate_*.toml``) and write one report of each claim, its
bound, the measured distribution and pass or fail (``gelrig.campaign.validate``).

Exit 0 when every measured claim passes, 1 when one fails, 2 for a bad option.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gelrig.commands.campaign import _workers


def _names(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed: campaign names, comma-separated")
    return names


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("validate", help="re-measure the README's claims (fit bias, interval "
                       "coverage, first touch, ...) with the built-in suite of campaigns")
    p.add_argument("--quick", action="store_true",
                   help="the small suite (each campaign's [validate.quick]; minutes, run by "
                        "the tests); default: the full suite (hours on Dask)")
    p.add_argument("--only", type=_names, default=[], metavar="NAMES",
                   help="only these campaigns of the suite (e.g. hold_plate,paper_ladder)")
    p.add_argument("--suite", default=None, metavar="DIR",
                   help="folder of validate_*.toml campaigns (default: the built-in suite)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="results folder (default campaigns/validate or validate-quick); a "
                        "rerun resumes, skipping members already done")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler; default: a LocalCluster")
    p.add_argument("--workers", type=_workers, default=None, metavar="N",
                   help="LocalCluster worker processes (default: the core count)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from gelrig.campaign.engine import run_members
    from gelrig.campaign.store import ResultStore
    from gelrig.campaign.validate import (
        evaluate,
        load_suite,
        suite_dir,
        summary_lines,
        write_validate_report,
    )

    directory = Path(args.suite) if args.suite else suite_dir()
    out = Path(args.out) if args.out else Path("campaigns") / (
        "validate-quick" if args.quick else "validate")
    suite = load_suite(directory, args.quick, args.only)  # every file checked before a run
    results = []
    for campaign in suite:
        where = out / campaign.name
        store = ResultStore(where, warn=lambda line: print(f"gelrig: warning: {line}",
                                                           file=sys.stderr))
        members = list(campaign.spec.members)
        print(f"validate {campaign.name}: {len(members)} member(s); claims "
              f"{', '.join(campaign.claims)}")
        run_members(members, store, workers=args.workers, scheduler=args.scheduler,
                    progress=not args.no_progress)
        rows = store.consolidate(m.member_id for m in members).to_pylist()
        results += evaluate(campaign, rows)
    command = "gelrig validate" + (" --quick" if args.quick else "") + (
        f" --only {','.join(args.only)}" if args.only else "")
    page = write_validate_report(out, "gelrig validate" + (" --quick" if args.quick else ""),
                                 results, [command])
    print("\n".join(summary_lines(results)))
    print(f"report: {page.resolve()}")
    failed = [r for r in results if r.verdict.status == "fail"]
    if failed:
        print(f"gelrig: {len(failed)} claim(s) failed: "
              f"{', '.join(f'{r.claim} ({r.campaign})' for r in failed)}", file=sys.stderr)
        return 1
    return 0
