"""``gelrig bringup RIG.toml``: confirm a rig's instrument facts, routine by routine, and
write them with their provenance into a confirmed rig file (gelrig.bringup)."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bringup", help="confirm the instruments' unverified facts at the rig "
                       "(scale, direction, load cell, rheometer commands) into a confirmed "
                       "rig file")
    p.add_argument("rig", metavar="RIG.toml", help="the rig file to confirm")
    p.add_argument("--operator", choices=("console", "twin"), default="console",
                   help="who answers: a person at this console (default), or the twin "
                        "(a simulated rig answering from its hidden truth: a rehearsal)")
    p.add_argument("--name", default="operator", metavar="NAME",
                   help="the operator's name, recorded beside each confirmed value")
    p.add_argument("--out", default=None, metavar="CONFIRMED.toml",
                   help="the confirmed rig file (default: RIG.confirmed.toml beside RIG.toml)")
    p.add_argument("--seed", type=int, default=0, help="the twin operator's reading errors")
    p.add_argument("--wire-log", action="store_true",
                   help="record every byte, RPC and line to and from each instrument, with "
                        "host times, into CONFIRMED.wire.jsonl beside the confirmed file")
    p.set_defaults(handler=cmd_bringup)


@contextlib.contextmanager
def _wire_log(args: argparse.Namespace, out: Path) -> Iterator[None]:
    """With ``--wire-log``, the instruments' exchanges go to ``out``'s ``.wire.jsonl``."""
    if not args.wire_log:
        yield
        return
    import os

    from gelrig.instrument.core import wire

    path = out.with_name(f"{out.stem}.wire.jsonl")
    header = {"argv": list(getattr(args, "argv", [])), "cwd": os.getcwd(),
              "command": "bringup"}
    with wire.recording(wire.WireLog(path, header)):
        yield
    print(f"wire log: {path}")


def cmd_bringup(args: argparse.Namespace) -> int:
    from gelrig.bringup import runner
    from gelrig.bringup.operator import ConsoleOperator, Operator
    from gelrig.instrument.core.clock import Clock
    from gelrig.protocols.rig import Rig
    from gelrig.protocols.rigfile import load_rig

    def make(rig: Rig, clock: Clock, source: str) -> Operator:
        if args.operator == "twin":
            return runner.twin_operator(rig, clock, source, args.seed)
        return ConsoleOperator(args.name)

    if args.operator == "twin":
        runner.check_twin(load_rig(args.rig))
    out = Path(args.out) if args.out else runner.default_out(Path(args.rig))
    with _wire_log(args, out):
        outcome = runner.run(Path(args.rig), make, out)
    print("\nFound:")
    for line in outcome.findings:
        print(f"  {line}")
    if outcome.written is None:
        print("Nothing written.")
        return 1 if not outcome.findings else 0
    print(f"Confirmed rig file: {outcome.written} ({len(outcome.accepted)} value(s); "
          f"{len(outcome.declined)} declined)")
    return 0
