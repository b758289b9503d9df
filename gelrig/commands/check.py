"""``gelrig check RIG.toml``: the conformance suite against whatever answers at the rig file's
addresses, twin or instrument (gelrig.conformance). Exit 0 when every check passes, 1 when one
fails, 2 for a bad rig file or an instrument that cannot be reached."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("check", help="run the same read-only (and, with --motion, small-motion) "
                       "checks against the rig's instruments or its twin")
    p.add_argument("rig", metavar="RIG.toml", help="the rig file")
    p.add_argument("--motion", action="store_true",
                   help="also move the stage 0.1 mm and back, under the interlocks (take the "
                        "sample off first)")
    p.set_defaults(handler=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    from gelrig.bringup.runner import connect
    from gelrig.conformance import check_rig
    from gelrig.protocols.rigfile import load_rig

    spec = load_rig(args.rig)
    rig, _ = connect(spec)
    try:
        results = check_rig(rig, motion=args.motion)
    finally:
        rig.close()
    where = "the twin" if spec.simulated else "the instruments"
    print(f"gelrig check {spec.source} ({where}):")
    for result in results:
        print(f"  {result.line()}")
    failed = sum(not r.passed for r in results)
    print(f"{len(results) - failed} of {len(results)} checks passed")
    return 1 if failed else 0
