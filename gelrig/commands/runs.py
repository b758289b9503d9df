"""``gelrig runs ROOT``: the runs under a folder, filtered, as a table or JSON; ``--compare``
puts runs side by side (ADR 0370)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from gelrig.instrument.core.errors import ConfigError

#: Columns of the table, with the catalog entry's key each shows.
TABLE = (("run", "name"), ("started", "started"), ("sample", "sample"),
         ("operator", "operator"), ("protocol", "protocol"), ("status", "status"),
         ("tags", "tags"), ("note", "note"))


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("runs", help="list, find and compare the runs under a folder")
    p.add_argument("root", metavar="ROOT", help="the folder of run folders (e.g. runs)")
    for name, help_text in (("sample", "a sample's name"), ("operator", "an operator"),
                            ("protocol", "a protocol's name"),
                            ("status", "completed, failed, aborted, refused, running or "
                                       "interrupted (killed mid-way)")):
        p.add_argument(f"--{name}", action="append", default=None, metavar=name.upper(),
                       help=f"only runs of {help_text} (repeatable; * and ? as wildcards)")
    p.add_argument("--tag", action="append", default=None, metavar="TAG",
                   help="only runs with this tag (repeatable: all of them)")
    p.add_argument("--since", default=None, metavar="WHEN",
                   help="only runs started at or after WHEN: 2026-11-25, 2026-11-25T08:00, "
                        "or an age such as 7d, 12h")
    p.add_argument("--until", default=None, metavar="WHEN",
                   help="only runs started before WHEN (a date: to the end of that day)")
    p.add_argument("--json", action="store_true",
                   help="a JSON array of runs (path, sample, operator, protocol, status, "
                        "started, finished, results with intervals) instead of the table")
    p.add_argument("--compare", nargs="+", default=None, metavar="RUN",
                   help="put these runs (folder names under ROOT, or paths) side by side: a "
                        "table of results with 95 %% intervals, and an overlay plot")
    p.add_argument("--plot", default=None, metavar="FILE.png",
                   help="where --compare writes its plot (default ROOT/compare.png)")
    p.set_defaults(handler=cmd_runs)


def _warn(line: str) -> None:
    print(f"gelrig: warning: {line}", file=sys.stderr)


def _filters(args: argparse.Namespace) -> dict[str, Any]:
    return {key: getattr(args, key) for key in ("sample", "operator", "protocol", "status",
                                                "tag", "since", "until")
            if getattr(args, key)}


def json_entry(entry: dict[str, Any]) -> dict[str, Any]:
    """One run as ``--json`` gives it."""
    from gelrig.catalog import flat_results

    keys = ("path", "name", "sample", "operator", "note", "tags", "protocol", "rig", "clock",
            "status", "recorded_status", "reason", "started", "finished")
    out = {key: entry.get(key) for key in keys}
    out["steps"] = [{k: s.get(k) for k in ("index", "name", "kind", "status", "samples")}
                    for s in entry.get("steps", [])]
    out["results"] = flat_results(entry)
    return out


def _console() -> Any:
    from rich.console import Console

    return Console(width=None if sys.stdout.isatty() else 160)


def cmd_runs(args: argparse.Namespace) -> int:
    from gelrig.catalog import find_runs

    if args.plot is not None and args.compare is None:
        raise ConfigError("--plot", args.plot, "goes with --compare RUN RUN...")
    from gelrig.instrument.core.catalog import parse_when

    for option in ("since", "until"):  # named as the user wrote them
        if getattr(args, option):
            parse_when(getattr(args, option), f"--{option}")
    root = Path(args.root)
    entries = find_runs(root, warn=_warn, **_filters(args))
    if args.compare is not None:
        return compare(root, args)
    if args.json:
        print(json.dumps([json_entry(e) for e in entries], indent=1))
        return 0
    from rich.table import Table

    table = Table(title=f"{len(entries)} run(s) in {root}", title_justify="left")
    for title, _ in TABLE:
        table.add_column(title, overflow="fold")
    for entry in entries:
        cells = []
        for _, key in TABLE:
            value = entry.get(key)
            text = ", ".join(value) if isinstance(value, list) else str(value or "")
            if key == "status" and entry.get("status") != entry.get("recorded_status"):
                text += f" (run.json: {entry.get('recorded_status')})"
            cells.append(text[:60])
        table.add_row(*cells)
    _console().print(table)
    return 0


def _pick(root: Path, refs: list[str]) -> list[dict[str, Any]]:
    """The catalog entries ``refs`` name: a run folder's name under ROOT, or its path."""
    from gelrig.catalog import find_runs

    every = {Path(e["path"]).resolve(): e for e in find_runs(root)}
    picked = []
    for ref in refs:
        path = Path(ref)
        if not (path / "run.json").is_file():
            path = root / ref
        entry = every.get(path.resolve())
        if entry is None:
            raise ConfigError("--compare", ref, f"a run folder under {root} (its name or its "
                              f"path; gelrig runs {root} lists them)")
        picked.append(entry)
    if len(picked) < 2:
        raise ConfigError("--compare", " ".join(refs), "two runs or more")
    return picked


def compare(root: Path, args: argparse.Namespace) -> int:
    """The side-by-side table (or JSON) and the overlay plot."""
    from gelrig.catalog import load_run
    from gelrig.compare import compare_rows, overlay_plot

    picked = _pick(root, list(args.compare))
    runs = [load_run(e["path"]) for e in picked]
    plot = Path(args.plot) if args.plot else root / "compare.png"
    if plot.suffix.lower() != ".png":
        raise ConfigError("--plot", str(plot), "a .png file")
    written, notes = overlay_plot(runs, plot)
    if args.json:
        print(json.dumps({"runs": [json_entry(e) for e in picked], "plot": str(written)},
                         indent=1))
    else:
        from rich.table import Table

        rows = compare_rows(picked)
        table = Table(title=f"{len(picked)} runs compared (95 % intervals)",
                      title_justify="left")
        for title in rows[0]:
            table.add_column(title, overflow="fold")
        for row in rows[1:]:
            table.add_row(*row)
        _console().print(table)
        print(f"plot: {written}")
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    return 0
