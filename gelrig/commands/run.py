"""``gelrig run | plan | resume | export``: protocols on a rig, from the command line."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gelrig.instrument.core.errors import ConfigError

if TYPE_CHECKING:  # rig files, drivers, data store and runner are imported when a command runs
    from collections.abc import Iterator

    from gelrig.instrument.core.store import RunDirectory
    from gelrig.protocols.events import RunState
    from gelrig.protocols.procedure import Procedure
    from gelrig.protocols.rehearsal import RehearsalReport
    from gelrig.protocols.rigfile import RigSpec
    from gelrig.protocols.runinfo import RunInfo

#: Exit code by the final RunState's value (refused: a step refused before it moved).
EXIT = {"completed": 0, "failed": 1, "aborted": 3, "refused": 2}


def register(sub: argparse._SubParsersAction) -> None:
    run = sub.add_parser("run", help="run a protocol on a rig, recording everything")
    _protocol_args(run)
    run.add_argument("--clock", default=None, metavar="real|virtual|paced:K",
                     help="time base (default: virtual on a simulated rig, real otherwise)")
    run.add_argument("--out", default=None, help="run directory (default runs/<time>-<rig>)")
    run_info_args(run)
    run.add_argument("--wire-log", action="store_true",
                     help="record every byte and RPC to and from each instrument, with host "
                          "times, into RUN_DIR/wire.jsonl (bounded; gelrig sim replay serves "
                          "it back to the drivers)")
    run.add_argument("--no-rehearse", action="store_true",
                     help="skip the rehearsal on the rig's twin before connecting (experts: a "
                          "script's later steps are then checked only as it sends them)")
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
    resume.add_argument("--sample", default=None, metavar="NAME",
                        help="the sample's name, if the run did not record the right one")
    run_info_args(resume)
    resume.add_argument("--out", default=None, metavar="NEW_DIR",
                        help="continue into a new folder (another disk): run.json and the step "
                             "files are copied there first")
    resume.set_defaults(handler=cmd_resume)

    export = sub.add_parser("export", help="write a run's data as CSV")
    export.add_argument("run_dir", metavar="RUN_DIR")
    export.add_argument("--csv", action="store_true", required=True, help="export as CSV")
    export.add_argument("--out", default=None, help="folder (default RUN_DIR/csv)")
    export.set_defaults(handler=cmd_export)


def run_info_args(parser: argparse.ArgumentParser) -> None:
    """``--operator``, ``--note``, ``--tag``: who ran the run and why (run.json, the catalog
    of ``gelrig runs``)."""
    parser.add_argument("--operator", default=None, metavar="NAME", help="who runs it")
    parser.add_argument("--note", default=None, metavar="TEXT", help="a note on the run")
    parser.add_argument("--tag", action="append", default=[], metavar="TAG",
                        help="a tag to find the run by (repeatable)")


def _protocol_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("protocol", metavar="PROTOCOL",
                        help="protocol file (.toml), script (.py; docs/scripting.md), or "
                             "paper:compression / paper:shear")
    parser.add_argument("--rig", default=None, metavar="RIG.toml",
                        help="rig file (default: the built-in simulated rig for the protocol)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a script's parameter (repeatable): VALUE as in TOML, e.g. "
                             "--param strains=[0.02,0.04] --param hold='600 s'")
    parser.add_argument("--sample", default=None, metavar="NAME|SAMPLE.toml",
                        help="the sample on the rig: its NAME (the protocol's sample renamed, "
                             "its sizes kept; it names the run folder), or a TOML file with a "
                             "[sample] table (name, diameter or r1 and r2, material) that "
                             "replaces the protocol's")
    parser.add_argument("--sample-diameter", default=None, metavar="DIAMETER",
                        help="the sphere's diameter, e.g. \"12 mm\" (steps that need a size "
                             "take it from the sample; none is assumed)")


def resolve(args: argparse.Namespace) -> tuple[Procedure, RigSpec]:
    """The procedure and the rig the options name (one resolver for every front end)."""
    from gelrig.protocols.resolve import parse_params, resolve_procedure, resolve_rig
    from gelrig.protocols.sample import sample_from_options

    procedure = resolve_procedure(args.protocol, parse_params(args.param))
    sample = sample_from_options(args.sample, args.sample_diameter, base=procedure.sample)
    if sample is not None:
        procedure = resolve_procedure(procedure, sample=sample)
    return procedure, resolve_rig(args.rig, procedure)


def run_info_of(args: argparse.Namespace) -> RunInfo:
    """``--operator``, ``--note`` and ``--tag`` checked (one line, exit 2 otherwise)."""
    from gelrig.protocols.runinfo import run_info

    return run_info(args.operator, args.note, args.tag)


def print_plan(protocol: Procedure, rig: RigSpec) -> list[str]:
    """Print the plan; returns the messages of failed limit checks."""
    from gelrig.protocols.plan import dry_run
    from gelrig.protocols.spec import ProtocolSpec

    print(f"Protocol: {protocol.name}  ({protocol.source})")
    print(f"Rig:      {rig.name}  ({rig.source}{', simulated' if rig.simulated else ''})")
    sample = protocol.sample
    print(f"Sample:   {sample.describe() if sample is not None else 'none given'}")
    if not isinstance(protocol, ProtocolSpec):
        given = getattr(protocol, "params", {})
        if given:
            print("Params:   " + ", ".join(f"{k} = {v!r}" for k, v in given.items()))
        print("Steps:    decided by the script as it runs; `gelrig plan` rehearses it on the "
              "rig's twin")
        return []
    summary = dry_run(protocol, rig.limits)
    if summary.beyond is not None:  # refused before anything is built or printed
        raise summary.beyond.error(protocol.source)
    for line in summary.lines[1:]:  # the first repeats the protocol's name
        print(f"\n{line}" if line[:1].isdigit() or line.startswith("Total") else line)
    return summary.failed


def rehearsal_log() -> Path:
    """Where a rehearsal's log goes (tracebacks included; the console gets one line): one file
    in the temporary folder, written afresh by each rehearsal."""
    import tempfile

    return Path(tempfile.gettempdir()) / "gelrig-rehearsal.log"


def rehearse_on_twin(protocol: Procedure, rig: RigSpec) -> tuple[RehearsalReport, float]:
    """``protocol`` rehearsed on ``rig``'s twin in virtual time (any rig, simulated or not),
    its log in :func:`rehearsal_log` instead of on the console; the report and the wall
    seconds it took."""
    import time

    from gelrig.factory import build_twin
    from gelrig.protocols.host import run_logging
    from gelrig.protocols.rehearsal import rehearse

    path = rehearsal_log()
    with contextlib.suppress(OSError):
        path.unlink()
    started = time.perf_counter()
    with run_logging(path):
        twin = build_twin(rig)
        try:
            report = rehearse(twin, protocol)
        finally:
            twin.close()
    return report, time.perf_counter() - started


def cmd_plan(args: argparse.Namespace) -> int:
    """The static plan as a header, then the rehearsal on the rig's twin; 2 if it fails."""
    from gelrig.instrument.core.paths import check_path

    out = Path(args.out) if args.out else Path("runs")
    check_path(out)
    protocol, rig = resolve(args)
    failed = print_plan(protocol, rig)
    if failed:
        raise ConfigError("limit check", failed[0], "fix the protocol or the rig limits")
    print("\nRehearsal on the rig's twin (each instrument's simulator, same limits, "
          "virtual time):", flush=True)
    report, _ = rehearse_on_twin(protocol, rig)
    for line in report.lines():
        print(f"\n{line}" if line.startswith("Total") else line)
    warning = disk_warning(out, report.bytes)
    if warning:
        print(warning)
    if not report.ok:
        print(f"gelrig plan: {report.failure()} (details: {rehearsal_log()})",
              file=sys.stderr)
        return 2
    return 0


#: HDF5 files hold a little more than their columns (chunk indices, attributes).
_STORE_OVERHEAD = 1.05


def disk_warning(out: Path, data_bytes: int) -> str:
    """A warning line when the disk under ``out`` (or its nearest existing parent) has less
    free space than the run would write; '' when it has room."""
    import shutil

    from gelrig.instrument.core.paths import check_path, existing_parent
    from gelrig.protocols.rehearsal import human_bytes

    check_path(out)
    where = existing_parent(out).resolve()
    free = shutil.disk_usage(where).free
    need = data_bytes * _STORE_OVERHEAD
    if free >= need:
        return f"Output disk ({where}): {human_bytes(free)} free, the run writes about " \
               f"{human_bytes(need)}"
    return (f"WARNING: output disk ({where}) has {human_bytes(free)} free; the run writes "
            f"about {human_bytes(need)}")


def cmd_run(args: argparse.Namespace) -> int:
    from gelrig.factory import build_rig
    from gelrig.instrument.core.store import check_out_dir
    from gelrig.instrument.core.units import lab_time
    from gelrig.protocols.host import (
        RunHost,
        closing_rig,
        create_run,
        default_run_dir,
        discard_run,
        new_folders,
        preflight,
        refused_unmoved,
    )
    from gelrig.protocols.resolve import make_clock
    from gelrig.terminal import run_in_terminal

    protocol, rig = resolve(args)
    info = run_info_of(args)
    out = Path(args.out) if args.out else default_run_dir(protocol)
    check_out_dir(out)
    failed = print_plan(protocol, rig)
    if failed:
        raise ConfigError("limit check", failed[0], "fix the protocol or the rig limits")
    clock, spec = make_clock(args.clock, rig)
    if not args.no_rehearse:  # the whole procedure on the twin before any instrument is opened
        print("\nrehearsing on the rig's twin (virtual time) ...", flush=True)
        report, wall = rehearse_on_twin(protocol, rig)
        if not report.ok:  # a refusal reads as the run's own would; anything else says where
            tail = "" if report.refusal else (" (found by the rehearsal on the rig's twin: "
                                              "nothing was connected or moved; details: "
                                              f"{rehearsal_log()})")
            print(f"gelrig run: {report.failure()}{tail}", file=sys.stderr)
            return 2
        print(f"rehearsal passed in {wall:.1f} s: {len(report.steps)} steps, "
              f"{lab_time(report.total)} lab time, {report.samples:,} samples "
              "(--no-rehearse skips it)")
    # an instrument that cannot be reached, or a step beyond the built rig's caps, is
    # refused before the run folder is made (exit 2, one line)
    with wire_log(args, out) as moved, closing_rig(build_rig(rig, clock)) as built:
        refused = preflight(built, protocol)
        if refused:
            return refuse("run", refused[0])
        made = new_folders(out)
        run = create_run(protocol, rig, spec, out, info)
        moved.append(run.path / "wire.jsonl")
        with RunHost(built, protocol, run) as host:
            print(f"\nrecording to {out.resolve()} ({spec} clock)")
            state = run_in_terminal(host)
    # a script's step refused before anything of the run moved: as if refused up front
    problem = refused_unmoved(host)
    if problem:
        discard_run(run, made)
        return refuse("run", problem)
    return _finish(run, state.value, host.reason)


@contextlib.contextmanager
def wire_log(args: argparse.Namespace, out: Path) -> Iterator[list[Path]]:
    """With ``--wire-log``, record the instruments' exchanges while the block runs (beside
    ``out`` until the run folder exists); the caller appends where the log goes once the run
    folder is made, and it is moved there at the end (removed if no folder was made)."""
    target: list[Path] = []
    if not getattr(args, "wire_log", False):
        yield target
        return
    import os

    from gelrig.instrument.core import wire

    temp = out.parent / f".{out.name}.wire.jsonl"
    header = {"argv": list(getattr(args, "argv", [])), "cwd": os.getcwd(), "command": "run"}
    try:
        with wire.recording(wire.WireLog(temp, header)):
            yield target
    finally:
        if target and temp.exists():
            temp.replace(target[-1])
            print(f"wire log: {target[-1]}")
        else:
            temp.unlink(missing_ok=True)


def refuse(command: str, problem: str) -> int:
    """A protocol refused before anything moved: one line on stderr, exit code 2."""
    print(f"gelrig {command}: {problem}; refused before anything moves", file=sys.stderr)
    return 2


def _finish(run: RunDirectory, state: str, reason: str, quiet: bool = False) -> int:
    """Summarise; the exit code follows run.json's final status (a storage fault found while
    closing the last step turns a completed run into a failed one). ``quiet``: the summary
    only, nothing on stderr (the caller prints the one line)."""
    meta = run.read_metadata()
    status = str(meta.get("status", state))
    summarise(run, status, str(meta.get("reason") or reason))
    if quiet:
        return EXIT.get(status, 1)
    fault = meta.get("storage_fault")
    if fault:
        print(f"gelrig: {fault}; the run is marked failed. Continue it elsewhere with: "
              f"gelrig resume {run.path} --out NEW_DIR", file=sys.stderr)
    return EXIT.get(status, 1)


def cmd_resume(args: argparse.Namespace) -> int:
    from gelrig.factory import build_rig
    from gelrig.instrument.core.store import RunDirectory
    from gelrig.protocols.host import (
        RunHost,
        closing_rig,
        preflight,
        prepare_resume,
        refused_unmoved,
        resumable,
    )
    from gelrig.protocols.interactive import refuse_interactive
    from gelrig.protocols.resolve import make_clock, resolve_rig
    from gelrig.terminal import run_in_terminal

    source = RunDirectory(args.run_dir)
    changes = resume_metadata(args)
    refuse_interactive(source.read_metadata(), str(source.path))  # continued from Python
    if source.read_metadata().get("status") == "completed":
        print(f"{source.path} already completed; nothing to resume")
        return 0
    meta, protocol, notes = resumable(source)
    for note in notes:
        print(f"note: {note}")
    rig = resolve_rig(meta["rig"], protocol, source=str(meta.get("rig_file", "<run.json>")))
    clock, spec = make_clock(args.clock or meta.get("clock"), rig)
    with contextlib.ExitStack() as held:
        held.enter_context(source.lock())
        # the rig built and the steps left checked against its caps before anything is
        # copied or archived: a refusal leaves the run as it was (exit 2, one line)
        built = held.enter_context(closing_rig(build_rig(rig, clock)))
        done = {i: s.get("results") or {} for i, s in source.completed_steps().items()}
        refused = preflight(built, protocol, done)
        if refused:
            return refuse("resume", refused[0])
        run = source
        if args.out:
            run = source.copy_to(args.out)
            held.enter_context(run.lock())
            print(f"copied {source.path} to {run.path}")
        if changes:
            run.update(**merged_metadata(run.read_metadata(), changes))
        completed, archived = prepare_resume(run, meta, spec, clock)
        print(f"resuming {run.path}: steps {sorted(completed) or 'none'} done"
              + (f"; kept partial data as {', '.join(archived)}" if archived else ""))
        with RunHost(built, protocol, run, completed=completed, lock=False) as host:
            state = run_in_terminal(host)
    problem = refused_unmoved(host)  # the run's folder and its data stay as they are
    if problem:
        _finish(run, state.value, host.reason, quiet=True)
        return refuse("resume", problem)
    return _finish(run, state.value, host.reason)


def resume_metadata(args: argparse.Namespace) -> dict[str, Any]:
    """What ``gelrig resume --sample/--operator/--note/--tag`` changes in run.json."""
    from gelrig.protocols.runinfo import run_info
    from gelrig.protocols.sample import check_sample_name

    info = run_info(args.operator, args.note, args.tag)
    changes: dict[str, Any] = {}
    if args.sample is not None:
        changes["sample_name"] = check_sample_name(args.sample)
    if args.operator is not None:
        changes["operator"] = info.operator
    if args.note is not None:
        changes["note"] = info.note
    if info.tags:
        changes["tags"] = list(info.tags)
    return changes


def merged_metadata(meta: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """run.json's fields after a resume's changes: a new sample name, operator or note
    replaces the recorded one; tags are added."""
    out = {k: v for k, v in changes.items() if k not in ("sample_name", "tags")}
    if "sample_name" in changes:
        sample = meta.get("sample")
        out["sample"] = {**(sample if isinstance(sample, dict) else {}),
                         "name": changes["sample_name"]}
    if "tags" in changes:
        old = [t for t in meta.get("tags") or [] if isinstance(t, str)]
        out["tags"] = old + [t for t in changes["tags"] if t not in old]
    return out


def cmd_export(args: argparse.Namespace) -> int:
    import shutil

    from gelrig.instrument.core.csvio import CSV_BYTES_PER_VALUE, write_chunks
    from gelrig.instrument.core.store import (
        RunDirectory,
        StorageFault,
        check_path,
        describe_io_error,
        existing_parent,
        open_step,
    )

    run = RunDirectory(args.run_dir)
    meta = run.read_metadata()
    out = Path(args.out) if args.out else run.path / "csv"
    check_path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", str(out), "is a file, not a folder; name a folder")
    written, damaged = [], []
    for step in [*meta["steps"], *meta.get("interrupted_steps", [])]:
        path = run.step_file(step)
        if not path.exists() and not path.is_symlink():
            print(f"step {step['index']} ({step['name']}): {step['file']} is missing")
            continue
        target = out / (Path(step["file"]).stem + ".csv")
        try:
            with open_step(path) as data:  # every check made before a row is read
                need = data.rows * len(data.names) * CSV_BYTES_PER_VALUE
                free = shutil.disk_usage(existing_parent(out)).free
                if need > free:
                    raise ConfigError("--out", str(out), f"has {free / 1e9:.1f} GB free; "
                                      f"{step['file']} ({data.rows:,} rows x "
                                      f"{len(data.names)} columns) takes up to "
                                      f"{need / 1e9:.1f} GB as CSV")
                rows = write_chunks(target, data.names, data.chunks())
        except ConfigError as exc:
            if exc.field == "--out":
                raise
            damaged.append(exc)
            print(f"step {step['index']} ({step['name']}): skipped, {exc}")
            continue
        except OSError as exc:
            raise StorageFault(f"{describe_io_error(exc)} writing {target}") from None
        written.append(target)
        print(f"{target} ({rows} rows, {step['status']})")
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "run.json").write_text(json.dumps(meta, indent=2))
    except OSError as exc:
        raise StorageFault(f"{describe_io_error(exc)} writing {out / 'run.json'}") from None
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
        for line in fit_lines(results.get("fits", [])):
            print(f"     {line}")
    print(f"data: {run.path.resolve()}  (gelrig export {run.path} --csv)")


def _se(fit: dict[str, Any], name: str) -> str:
    value = (fit.get("stderr") or {}).get(name)
    return f" +- {value:.2g}" if isinstance(value, int | float) else " +- undetermined"


def _term(fit: dict[str, Any], i: int, r: dict[str, Any]) -> str:
    """``G_i ... Pa, tau_i ... s`` with standard errors, G_i the material's (ramp-corrected)
    where the fit carries it."""
    from gelrig.instrument.analysis.relaxation import shown_amplitude

    g, note = shown_amplitude(fit, i, float(r["G"]))
    se = (fit.get("stderr") or {}).get(f"G_{i}")
    scaled = {"stderr": {f"G_{i}": se * g / float(r["G"])}} \
        if isinstance(se, int | float) and r["G"] else fit
    return (f"G_{i} {g:.0f}{_se(scaled, f'G_{i}')} Pa{note}, tau_{i} {r['tau']:.0f}"
            f"{_se(fit, f'tau_{i}')} s")


def fit_lines(fits: list[dict[str, Any]]) -> list[str]:
    """run.json's fits of a hold as end-of-run lines: each term count once, with standard
    errors; a count the data do not resolve is ``not resolved: <reason>``, without values."""
    out = []
    for k, fit in enumerate(fits, start=1):
        if "error" in fit:
            out.append(f"{k}-term fit failed: {fit['error']}")
            continue
        requested = int(fit.get("terms_requested", len(fit.get("relax") or [])))
        resolved = fit.get("resolved", int(fit.get("terms_resolved", 0)) >= requested)
        if not resolved or requested != len(fit.get("relax") or []):
            why = fit.get("not_resolved") or "not every term is resolved"
            out.append(f"{requested}-term fit: not resolved: {why}")
            continue
        terms = ", ".join(_term(fit, i, r) for i, r in enumerate(fit["relax"], 1))
        out.append(f"{requested}-term fit: G_e {fit['G_e']:.0f}{_se(fit, 'G_e')} Pa, {terms}")
    return out


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
