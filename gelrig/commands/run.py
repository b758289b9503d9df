"""``gelrig run | plan | resume | export``: protocols on a rig, from the command line."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from instrument.errors import ConfigError

if TYPE_CHECKING:  # rig files, drivers, data store and runner are imported when a command runs
    from instrument.store import RunDirectory
    from protocols.events import RunState
    from protocols.procedure import Procedure
    from protocols.rigfile import RigSpec

#: Exit code by the final RunState's value.
EXIT = {"completed": 0, "failed": 1, "aborted": 3}


def register(sub: argparse._SubParsersAction) -> None:
    run = sub.add_parser("run", help="run a protocol on a rig, recording everything")
    _protocol_args(run)
    run.add_argument("--clock", default=None, metavar="real|virtual|paced:K",
                     help="time base (default: virtual on a simulated rig, real otherwise)")
    run.add_argument("--out", default=None, help="run directory (default runs/<time>-<rig>)")
    run.set_defaults(handler=cmd_run)

    plan = sub.add_parser("plan", help="rehearse a protocol on the rig's simulated twin: "
                          "lab time, travel, limits hit, data volume")
    _protocol_args(plan)
    plan.add_argument("--out", default=None,
                      help="where the run would record (for the disk-space check; default runs/)")
    plan.set_defaults(handler=cmd_plan)

    resume = sub.add_parser("resume", help="continue a run from its last completed step")
    resume.add_argument("run_dir", metavar="RUN_DIR")
    resume.add_argument("--clock", default=None, metavar="real|virtual|paced:K")
    resume.add_argument("--out", default=None, metavar="NEW_DIR",
                        help="continue into a new folder (another disk): run.json and the step "
                             "files are copied there first")
    resume.set_defaults(handler=cmd_resume)

    export = sub.add_parser("export", help="write a run's data as CSV")
    export.add_argument("run_dir", metavar="RUN_DIR")
    export.add_argument("--csv", action="store_true", required=True, help="export as CSV")
    export.add_argument("--out", default=None, help="folder (default RUN_DIR/csv)")
    export.set_defaults(handler=cmd_export)


def _protocol_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("protocol", metavar="PROTOCOL",
                        help="protocol file (.toml), script (.py; docs/scripting.md), or "
                             "paper:compression / paper:shear")
    parser.add_argument("--rig", default=None, metavar="RIG.toml",
                        help="rig file (default: the built-in simulated rig for the protocol)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a script's parameter (repeatable): VALUE as in TOML, e.g. "
                             "--param strains=[0.02,0.04] --param hold='600 s'")


def resolve_protocol(name: str, params: list[str] | None = None) -> Procedure:
    """The protocol ``name`` names; a script called with ``params`` (``NAME=VALUE``)."""
    from protocols.script import Script, load_procedure

    procedure = load_procedure(name)
    if not params:
        return procedure
    if not isinstance(procedure, Script):
        raise ConfigError("--param", params[0], "only scripts (.py) take parameters; a "
                          "protocol file's are in the file")
    return procedure.with_params(**dict(_param(text) for text in params))


def _param(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` with VALUE read as a TOML value (a bare word stays a string)."""
    import tomllib

    name, eq, value = text.partition("=")
    if not eq or not name.strip().isidentifier():
        raise ConfigError("--param", text, "NAME=VALUE, e.g. hold='600 s' or strain=0.04")
    try:
        return name.strip(), tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        return name.strip(), value


def resolve_rig(path: str | None, protocol: Procedure) -> RigSpec:
    from protocols.rigfile import default_rig, load_rig

    rig = load_rig(path if path else default_rig(protocol.rig))
    if rig.kind != protocol.rig:
        raise ConfigError("--rig", rig.source, f"is a {rig.kind} rig; protocol "
                          f"{protocol.source} needs a {protocol.rig} rig")
    return rig


def print_plan(protocol: Procedure, rig: RigSpec) -> list[str]:
    """Print the plan; returns the messages of failed limit checks."""
    from protocols.plan import dry_run
    from protocols.spec import ProtocolSpec

    print(f"Protocol: {protocol.name}  ({protocol.source})")
    print(f"Rig:      {rig.name}  ({rig.source}{', simulated' if rig.simulated else ''})")
    if not isinstance(protocol, ProtocolSpec):
        given = getattr(protocol, "params", {})
        if given:
            print("Params:   " + ", ".join(f"{k} = {v!r}" for k, v in given.items()))
        print("Steps:    decided by the script as it runs; `gelrig plan` rehearses it on the "
              "rig's twin")
        return []
    summary = dry_run(protocol, rig.limits)
    for line in summary.lines[1:]:  # the first repeats the protocol's name
        print(f"\n{line}" if line[:1].isdigit() or line.startswith("Total") else line)
    return summary.failed


def cmd_plan(args: argparse.Namespace) -> int:
    """The static plan as a header, then the rehearsal on the rig's twin; 2 if it fails."""
    import sys

    from gelrig.factory import build_twin
    from protocols.rehearsal import rehearse

    protocol = resolve_protocol(args.protocol, args.param)
    rig = resolve_rig(args.rig, protocol)
    failed = print_plan(protocol, rig)
    if failed:
        raise ConfigError("limit check", failed[0], "fix the protocol or the rig limits")
    print("\nRehearsal on the rig's twin (each instrument's simulator, same limits, "
          "virtual time):", flush=True)
    twin = build_twin(rig)
    try:
        report = rehearse(twin, protocol)
    finally:
        twin.close()
    for line in report.lines():
        print(f"\n{line}" if line.startswith("Total") else line)
    warning = disk_warning(Path(args.out) if args.out else Path("runs"), report.bytes)
    if warning:
        print(warning)
    if not report.ok:
        print(f"gelrig plan: {report.failure()}", file=sys.stderr)
        return 2
    return 0


#: HDF5 files hold a little more than their columns (chunk indices, attributes).
_STORE_OVERHEAD = 1.05


def disk_warning(out: Path, data_bytes: int) -> str:
    """A warning line when the disk under ``out`` (or its nearest existing parent) has less
    free space than the run would write; '' when it has room."""
    import shutil

    from protocols.rehearsal import human_bytes

    where = out.resolve()
    while not where.exists() and where != where.parent:
        where = where.parent
    free = shutil.disk_usage(where).free
    need = data_bytes * _STORE_OVERHEAD
    if free >= need:
        return f"Output disk ({where}): {human_bytes(free)} free, the run writes about " \
               f"{human_bytes(need)}"
    return (f"WARNING: output disk ({where}) has {human_bytes(free)} free; the run writes "
            f"about {human_bytes(need)}")


def cmd_run(args: argparse.Namespace) -> int:
    from gelrig.session import LOG_NAME, default_run_dir, execute, make_clock, new_run
    from instrument.store import check_out_dir

    protocol = resolve_protocol(args.protocol, args.param)
    rig = resolve_rig(args.rig, protocol)
    out = Path(args.out) if args.out else default_run_dir(protocol)
    check_out_dir(out)
    failed = print_plan(protocol, rig)
    if failed:
        raise ConfigError("limit check", failed[0], "fix the protocol or the rig limits")
    clock, spec = make_clock(args.clock, rig)
    run = new_run(protocol, rig, spec, out)
    with run.lock():
        print(f"\nrecording to {out.resolve()} ({spec} clock)")
        try:
            state, runner = execute(protocol, rig, clock, run)
        except ConfigError:  # e.g. an instrument that cannot be reached: nothing recorded
            if run.read_metadata().get("status") == "created":
                run.discard_empty(also=(LOG_NAME,))
            raise
        return _finish(run, state.value, runner.reason)


def _finish(run: RunDirectory, state: str, reason: str) -> int:
    """Summarise; the exit code follows run.json's final status (a storage fault found while
    closing the last step turns a completed run into a failed one)."""
    meta = run.read_metadata()
    status = str(meta.get("status", state))
    summarise(run, status, str(meta.get("reason") or reason))
    fault = meta.get("storage_fault")
    if fault:
        print(f"gelrig: {fault}; the run is marked failed. Continue it elsewhere with: "
              f"gelrig resume {run.path} --out NEW_DIR", file=sys.stderr)
    return EXIT.get(status, 1)


def cmd_resume(args: argparse.Namespace) -> int:
    from gelrig.session import execute, make_clock, prepare_resume, resumable
    from instrument.store import RunDirectory
    from protocols.rigfile import parse_rig

    source = RunDirectory(args.run_dir)
    if source.read_metadata().get("status") == "completed":
        print(f"{source.path} already completed; nothing to resume")
        return 0
    meta, protocol, notes = resumable(source)
    for note in notes:
        print(f"note: {note}")
    rig = parse_rig(meta["rig"], meta.get("rig_file", "<run.json>"))
    clock, spec = make_clock(args.clock or meta.get("clock"), rig)
    with contextlib.ExitStack() as held:
        held.enter_context(source.lock())
        run = source
        if args.out:
            run = source.copy_to(args.out)
            held.enter_context(run.lock())
            print(f"copied {source.path} to {run.path}")
        completed, archived = prepare_resume(run, meta, spec)
        print(f"resuming {run.path}: steps {sorted(completed) or 'none'} done"
              + (f"; kept partial data as {', '.join(archived)}" if archived else ""))
        state, runner = execute(protocol, rig, clock, run, completed)
        return _finish(run, state.value, runner.reason)


def cmd_export(args: argparse.Namespace) -> int:
    from instrument.csvio import write_columns
    from instrument.store import RunDirectory, read_step

    run = RunDirectory(args.run_dir)
    meta = run.read_metadata()
    out = Path(args.out) if args.out else run.path / "csv"
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", str(out), "is a file, not a folder; name a folder")
    written, damaged = [], []
    for step in [*meta["steps"], *meta.get("interrupted_steps", [])]:
        path = run.step_file(step)
        if not path.exists() and not path.is_symlink():
            print(f"step {step['index']} ({step['name']}): {step['file']} is missing")
            continue
        try:
            data = read_step(path)
        except ConfigError as exc:
            damaged.append(exc)
            print(f"step {step['index']} ({step['name']}): skipped, {exc}")
            continue
        target = out / (Path(step["file"]).stem + ".csv")
        write_columns(target, data)
        written.append(target)
        n = len(next(iter(data.values()))) if data else 0
        print(f"{target} ({n} rows, {step['status']})")
    (out / "run.json").write_text(json.dumps(meta, indent=2))
    print(f"exported {len(written)} step(s) to {out.resolve()}")
    if damaged:
        raise damaged[0]
    return 0


def summarise(run: RunDirectory, state: RunState | str, reason: str) -> None:
    meta = run.read_metadata()
    print(f"\nrun {getattr(state, 'value', state)}: {reason}")
    for step in meta["steps"]:
        results = step.get("results") or {}
        brief = {k: v for k, v in results.items() if isinstance(v, int | float | str)}
        samples = step.get('samples', 0)
        print(f"  {step['index']}. {step['name']}: {step['status']}, {samples} samples"
              + (f"; {_brief(brief)}" if brief else ""))
        for fit in results.get("fits", []):
            if "G_e" in fit:
                terms = ", ".join(f"G {r['G']:.0f} Pa tau {r['tau']:.0f} s" for r in fit["relax"])
                print(f"     fit: G_e {fit['G_e']:.0f} Pa, {terms}")
    print(f"data: {run.path.resolve()}  (gelrig export {run.path} --csv)")


def _brief(values: dict[str, Any]) -> str:
    out = []
    for key, value in values.items():
        if isinstance(value, float) and key.endswith("_m"):
            out.append(f"{key[:-2]} {value * 1e3:.4f} mm")
        elif isinstance(value, float):
            out.append(f"{key} {value:.4g}")
        else:
            out.append(f"{key} {value}")
    return ", ".join(out)
