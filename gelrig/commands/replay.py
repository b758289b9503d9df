"""``gelrig sim replay LOG``: a run's wire log served back to the same drivers (issue 30).

The log's header holds the command line it was recorded under (``gelrig run ...
--wire-log``); the run is made again, in virtual time, with every instrument replaced by the
recording: each exchange is checked against the next recorded one of that instrument, the
instrument's answer comes from the log, the clock follows the recorded host times. A replay
that diverges says where (instrument, call, recorded host time, both sides) and exits 1.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sim_sub: argparse._SubParsersAction) -> None:
    p = sim_sub.add_parser("replay", help="serve a recorded wire log back to the drivers: the "
                           "run again, every exchange checked against the recording")
    p.add_argument("log", metavar="LOG", help="a wire log (RUN_DIR/wire.jsonl of gelrig run "
                   "--wire-log)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="the replayed run's folder (default: RUN_DIR-replay beside RUN_DIR)")
    p.set_defaults(handler=cmd_replay)


def _options(argv: list[str], out: Path) -> list[str]:
    """The recorded ``gelrig run`` argv, replayed: no new log, no rehearsal, virtual time,
    the given output folder."""
    dropped = {"--wire-log", "--no-rehearse"}
    valued = {"--out", "--clock"}
    kept: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
            continue
        name = arg.split("=", 1)[0]
        if name in dropped:
            continue
        if name in valued:
            skip = "=" not in arg
            continue
        kept.append(arg)
    return [*kept, "--no-rehearse", "--clock", "virtual", "--out", str(out)]


def cmd_replay(args: argparse.Namespace) -> int:
    import contextlib

    from gelrig.cli import main
    from gelrig.instrument.core import wire
    from gelrig.instrument.core.errors import ConfigError

    path = Path(args.log)
    if not path.is_file():
        raise ConfigError("LOG", args.log, "a wire log file (RUN_DIR/wire.jsonl)")
    replay = wire.Replay(path)
    argv = list(replay.header.get("argv") or [])
    if not argv or argv[0] != "run":
        raise ConfigError("LOG", args.log, "a wire log recorded by gelrig run --wire-log "
                          f"(its header names {argv[:1] or 'no command'})")
    out = Path(args.out) if args.out else path.parent.with_name(path.parent.name + "-replay")
    out = out.resolve()
    cwd = replay.header.get("cwd")
    with wire.replaying(replay), (contextlib.chdir(cwd) if cwd and Path(cwd).is_dir()
                                  else contextlib.nullcontext()):
        code = main(_options(argv, out))
    total = sum(replay.recorded.values())
    served = sum(replay.served().values())
    left = replay.left()
    if left:
        first = ", ".join(f"{name} from call {replay.served().get(name, 0)}"
                          for name in sorted(left))
        print(f"gelrig sim replay: diverged: {served} of {total} recorded exchanges served; "
              f"not reached: {first}")
        return 1
    print(f"gelrig sim replay: {served} of {total} recorded exchanges served, every one as "
          f"recorded; the replayed run is {out}")
    return code
