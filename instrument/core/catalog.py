"""The catalog of runs: an SQLite index of the run folders under one root (ADR 0370).

``ROOT/.gelrig-runs.sqlite`` indexes each run folder ``ROOT/<name>/run.json``: its sample,
operator, note, tags, protocol, rig, clock, status, wall start and end, steps, and the
scalar results and fitted values of its steps (value, standard error, 95 % interval). The
folders stay the source of truth: an entry remembers the size and mtime of the run.json it
was read from, and :func:`catalog_entries` reads again every run.json that changed, drops
the folders that went, and rebuilds the whole index when the file is missing or is not an
SQLite database. Writing is never allowed to hold up a run: :func:`index_run` (called by
the run host as a run starts and ends) waits at most 0.1 s for a lock and returns one
warning line instead of raising. Standard library only (``gelrig runs --help`` stays fast).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import sqlite3
from collections.abc import Iterable, Iterator, Mapping
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from gelrig.instrument.core.errors import ConfigError

#: The index's file name in a runs root.
CATALOG_NAME = ".gelrig-runs.sqlite"
#: Bumped when the tables change: an index of another version is rebuilt.
SCHEMA_VERSION = 1
#: Longest wall time (s) the run host waits for the index's lock: a transient reader or
#: writer (``gelrig runs``) gets out of the way; one that holds it longer costs a warning.
WRITE_WAIT = 0.1
#: Largest run.json the catalog reads (bytes), as the store.
MAX_METADATA_BYTES = 64 * 1024 * 1024
#: z of a two-sided 95 % interval.
Z95 = 1.959963984540054
#: Statuses of a run that has not ended; with no live process holding its run.lock such a
#: run ended short (SIGKILL, a crash, power loss) and is listed as ``interrupted``.
OPEN_STATUSES = ("created", "running", "paused", "aborting", "idle")
INTERRUPTED = "interrupted"
#: Units of results by the suffix of their key (run.json keys carry the SI unit).
_UNITS = (("_m_s", "m/s"), ("_rad", "rad"), ("_N", "N"), ("_Pa", "Pa"), ("_s", "s"),
          ("_m", "m"))

_SCHEMA = """
CREATE TABLE IF NOT EXISTS info (key TEXT PRIMARY KEY, value TEXT);
CREATE TABLE IF NOT EXISTS runs (
    name TEXT PRIMARY KEY, mtime_ns INTEGER, size INTEGER, sample TEXT, operator TEXT,
    note TEXT, protocol TEXT, rig TEXT, clock TEXT, status TEXT, reason TEXT,
    started TEXT, finished TEXT, record TEXT);
CREATE TABLE IF NOT EXISTS tags (run TEXT, tag TEXT);
CREATE TABLE IF NOT EXISTS results (
    run TEXT, step INTEGER, step_name TEXT, quantity TEXT, value REAL, stderr REAL,
    lo REAL, hi REAL, unit TEXT);
CREATE INDEX IF NOT EXISTS results_run ON results (run);
CREATE INDEX IF NOT EXISTS tags_run ON tags (run);
"""


def catalog_path(root: str | os.PathLike[str]) -> Path:
    """The index file of the runs root ``root``."""
    return Path(root) / CATALOG_NAME


# ---- reading a run folder ------------------------------------------------------------------
def _read_json(path: Path) -> dict[str, Any] | None:
    """run.json as a dict, None when it is missing, too large or not a JSON object."""
    try:
        if path.stat().st_size > MAX_METADATA_BYTES:
            return None
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return raw if isinstance(raw, dict) else None


def _table(value: object) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}


def _list(value: object) -> list[Any]:
    return value if isinstance(value, list) else []


def _text(value: object) -> str:
    return value if isinstance(value, str) else ""


def _number(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _unit(key: str) -> str:
    return next((unit for suffix, unit in _UNITS if key.endswith(suffix)), "")


def _interval(value: float, se: float | None) -> tuple[float | None, float | None]:
    if se is None:
        return None, None
    return value - Z95 * se, value + Z95 * se


def step_results(step: Mapping[str, Any]) -> list[dict[str, Any]]:
    """A step record's scalar results and fitted values as rows: ``quantity``, ``value``,
    ``stderr``, ``lo``/``hi`` (95 %: value +- 1.96 stderr; None without a standard error),
    ``unit``. A hold's fits give ``G_e``, ``G_i``, ``tau_i`` per term count
    (``1-term G_e``), each with its standard error; unresolved fits are left out."""
    results = _table(step.get("results"))
    rows: list[dict[str, Any]] = []
    for key, raw in results.items():
        value = _number(raw)
        if value is None or key.endswith("_se_m") or key == "samples":
            continue
        se = _number(results.get(f"{key[:-2]}_se_m")) if key.endswith("_m") else None
        lo, hi = _interval(value, se)
        rows.append({"quantity": key, "value": value, "stderr": se, "lo": lo, "hi": hi,
                     "unit": _unit(key)})
    for fit in _list(results.get("fits")):
        if not isinstance(fit, Mapping) or "error" in fit or fit.get("resolved") is False:
            continue
        relax = _list(fit.get("relax"))
        terms = int(_number(fit.get("terms_requested")) or len(relax))
        stderr = _table(fit.get("stderr"))
        values: dict[str, tuple[float | None, str]] = {"G_e": (_number(fit.get("G_e")), "Pa")}
        for i, term in enumerate(relax, start=1):
            if isinstance(term, Mapping):
                values[f"G_{i}"] = (_number(term.get("G")), "Pa")
                values[f"tau_{i}"] = (_number(term.get("tau")), "s")
        for name, (value, unit) in values.items():
            if value is None:
                continue
            se = _number(stderr.get(name))
            lo, hi = _interval(value, se)
            rows.append({"quantity": f"{terms}-term {name}", "value": value, "stderr": se,
                         "lo": lo, "hi": hi, "unit": unit})
    return rows


def summarise_run(meta: Mapping[str, Any]) -> dict[str, Any]:
    """What the catalog keeps of one run.json (no folder, no liveness: see
    :func:`catalog_entries`)."""
    sample = _table(meta.get("sample"))
    head = _table(_table(meta.get("protocol")).get("protocol"))
    rig_head = _table(_table(meta.get("rig")).get("rig"))
    tags = _list(meta.get("tags"))
    steps = []
    for record in _list(meta.get("steps")):
        if not isinstance(record, Mapping):
            continue
        steps.append({"index": record.get("index"), "name": _text(record.get("name")),
                      "kind": _text(record.get("kind")), "status": _text(record.get("status")),
                      "samples": record.get("samples"), "results": step_results(record)})
    protocol_name = _text(head.get("name")) or Path(_text(meta.get("protocol_file"))).stem
    return {
        "sample": _text(sample.get("name")), "operator": _text(meta.get("operator")),
        "note": _text(meta.get("note")), "tags": [t for t in tags if isinstance(t, str)],
        "protocol": protocol_name, "rig": _text(rig_head.get("kind")),
        "clock": _text(meta.get("clock")), "status": _text(meta.get("status")) or "unknown",
        "reason": _text(meta.get("reason")),
        "started": _text(meta.get("started_wall")) or _text(meta.get("created")),
        "finished": _text(meta.get("finished_wall")), "steps": steps,
    }


def holder_pid(run_dir: Path) -> int | None:
    """The pid written in ``run_dir/run.lock`` by the process recording into it (None when
    the lock file is empty or missing: no process holds the run)."""
    try:
        text = (run_dir / "run.lock").read_text(encoding="utf-8", errors="replace")[:200]
    except OSError:
        return None
    found = re.match(r"process (\d+)", text)
    return int(found.group(1)) if found else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    except OSError:
        return False
    return True


def live_status(run_dir: Path, status: str) -> tuple[str, int | None]:
    """The status to list and the holder's pid: a run whose run.json still says it runs but
    whose recording process is gone is ``interrupted``."""
    if status not in OPEN_STATUSES:
        return status, None
    pid = holder_pid(run_dir)
    if pid is not None and _alive(pid):
        return status, pid
    return INTERRUPTED, pid


# ---- the index file ------------------------------------------------------------------------
@contextlib.contextmanager
def _connect(path: Path, timeout: float) -> Iterator[sqlite3.Connection]:
    """A connection that waits at most ``timeout`` s for a lock; closed on the way out."""
    con = sqlite3.connect(path, timeout=timeout, isolation_level=None)
    try:
        con.execute("PRAGMA journal_mode=DELETE")
        yield con
    finally:
        con.close()


def _prepare(con: sqlite3.Connection) -> bool:
    """Create the tables; False when the file holds another schema version (rebuild it)."""
    con.executescript(_SCHEMA)
    row = con.execute("SELECT value FROM info WHERE key = 'schema'").fetchone()
    if row is None:
        con.execute("INSERT INTO info VALUES ('schema', ?)", (str(SCHEMA_VERSION),))
        return True
    return str(row[0]) == str(SCHEMA_VERSION)


def _store(con: sqlite3.Connection, name: str, stat: os.stat_result | None,
           summary: Mapping[str, Any]) -> None:
    """Replace ``name``'s rows (inside the caller's transaction)."""
    _forget(con, name)
    con.execute("INSERT INTO runs VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)", (
        name, stat.st_mtime_ns if stat else None, stat.st_size if stat else None,
        summary["sample"], summary["operator"], summary["note"], summary["protocol"],
        summary["rig"], summary["clock"], summary["status"], summary["reason"],
        summary["started"], summary["finished"], json.dumps(summary)))
    con.executemany("INSERT INTO tags VALUES (?,?)", [(name, t) for t in summary["tags"]])
    con.executemany("INSERT INTO results VALUES (?,?,?,?,?,?,?,?,?)", [
        (name, step["index"], step["name"], r["quantity"], r["value"], r["stderr"], r["lo"],
         r["hi"], r["unit"]) for step in summary["steps"] for r in step["results"]])


def _forget(con: sqlite3.Connection, name: str) -> None:
    for table, key in (("runs", "name"), ("tags", "run"), ("results", "run")):
        con.execute(f"DELETE FROM {table} WHERE {key} = ?", (name,))  # fixed names


def _describe(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def index_run(run_dir: str | os.PathLike[str], status: str | None = None) -> str:
    """Index (or index again) one run in its root's catalog (``status``: the status run.json
    is about to record, else its own), waiting at most WRITE_WAIT for a lock:
    '' on success, else one warning line (a locked, read-only or damaged index: the run
    goes on, and :func:`catalog_entries` rebuilds the index later). Never raises."""
    run = Path(run_dir)
    path = catalog_path(run.parent)
    try:
        stat = (run / "run.json").stat()
        meta = _read_json(run / "run.json")
        if meta is None:
            return ""
        with _connect(path, timeout=WRITE_WAIT) as con:
            if not _prepare(con):
                return f"run index {path}: written by another gelrig version; " \
                       "`gelrig runs` rebuilds it"
            summary = summarise_run(meta)
            if status is not None:  # the next listing reads run.json again (its mtime)
                summary["status"] = status
            con.execute("BEGIN IMMEDIATE")
            try:
                _store(con, run.name, stat, summary)
                con.execute("COMMIT")
            except BaseException:
                con.execute("ROLLBACK")
                raise
    except Exception as exc:  # whatever it is, the run goes on
        return (f"run index {path} not updated ({_describe(exc)}); the run goes on, "
                "`gelrig runs` rebuilds the index")
    return ""


def _run_folders(root: Path) -> dict[str, os.stat_result]:
    """Each run folder directly under ``root`` (one holding a run.json): name -> its stat."""
    found = {}
    try:
        entries = list(os.scandir(root))
    except OSError:
        return {}
    for entry in entries:
        if entry.name.startswith(".") or not entry.is_dir(follow_symlinks=False):
            continue
        with contextlib.suppress(OSError):
            found[entry.name] = os.stat(Path(entry.path) / "run.json")
    return found


def _sync(con: sqlite3.Connection, root: Path, folders: Mapping[str, os.stat_result]) -> None:
    """Bring the index up to date with ``folders``: changed run.json read again, gone ones
    dropped."""
    known = {name: (mtime, size) for name, mtime, size in
             con.execute("SELECT name, mtime_ns, size FROM runs")}
    con.execute("BEGIN IMMEDIATE")
    try:
        for name in set(known) - set(folders):
            _forget(con, name)
        for name, stat in folders.items():
            if known.get(name) == (stat.st_mtime_ns, stat.st_size):
                continue
            meta = _read_json(root / name / "run.json")
            if meta is None:
                _forget(con, name)
                continue
            _store(con, name, stat, summarise_run(meta))
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise


def _rows(con: sqlite3.Connection) -> list[tuple[str, dict[str, Any]]]:
    return [(name, json.loads(record)) for name, record in
            con.execute("SELECT name, record FROM runs ORDER BY started, name")]


def _scan(root: Path) -> list[tuple[str, dict[str, Any]]]:
    """Every run under ``root`` read from its folder (when the index cannot be used)."""
    out = []
    for name in sorted(_run_folders(root)):
        meta = _read_json(root / name / "run.json")
        if meta is not None:
            out.append((name, summarise_run(meta)))
    return sorted(out, key=lambda row: (row[1]["started"], row[0]))


def catalog_entries(root: str | os.PathLike[str], warn: Any = None
                    ) -> list[dict[str, Any]]:
    """Every run under ``root``, oldest first, from the index brought up to date (built when
    missing; rebuilt when damaged or of another version). Each entry: ``path`` (the run
    folder), ``name``, the summary of :func:`summarise_run` and the ``status`` to list
    (:func:`live_status`), ``pid`` of a live holder. When the index cannot be written (a
    lock held for long, a read-only folder) the folders are read directly and ``warn``
    (a callable taking one line) is told why."""
    base = Path(root)
    folders = _run_folders(base)
    path = catalog_path(base)
    rows: list[tuple[str, dict[str, Any]]] | None = None
    for attempt in range(2):
        try:
            with _connect(path, timeout=2.0) as con:
                if not _prepare(con):
                    raise sqlite3.DatabaseError("another schema version")
                _sync(con, base, folders)
                rows = _rows(con)
            break
        except sqlite3.DatabaseError as exc:
            locked = isinstance(exc, sqlite3.OperationalError) and "locked" in str(exc)
            if attempt or locked or not path.exists():
                if warn is not None:
                    warn(f"run index {path} not used ({_describe(exc)}); read the run "
                         "folders instead")
                break
            if warn is not None:
                warn(f"run index {path} was damaged ({_describe(exc)}); rebuilt from the run "
                     "folders")
            with contextlib.suppress(OSError):
                path.unlink()
                for suffix in ("-journal", "-wal", "-shm"):
                    Path(f"{path}{suffix}").unlink(missing_ok=True)
        except OSError as exc:
            if warn is not None:
                warn(f"run index {path} not used ({_describe(exc)}); read the run folders "
                     "instead")
            break
    if rows is None:
        rows = _scan(base)
    entries = []
    for name, summary in rows:
        folder = base / name
        status, pid = live_status(folder, summary["status"])
        entries.append({"path": str(folder), "name": name, **summary,
                        "recorded_status": summary["status"], "status": status, "pid": pid})
    return entries


# ---- choosing runs -------------------------------------------------------------------------
#: The filters of :func:`select_entries` (``gelrig runs`` options, ``gelrig.runs`` keywords).
FILTERS = ("sample", "operator", "protocol", "status", "tag", "since", "until")
_AGO = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*(d|h|w)\s*$")


def parse_when(text: object, field: str) -> datetime:
    """A time a run started after or before: ISO (``2026-11-25``, ``2026-11-25T08:00``,
    local time unless an offset is given) or an age (``7d``, ``12h``, ``2w`` ago)."""
    if isinstance(text, datetime):
        return text if text.tzinfo else text.astimezone()
    raw = str(text)
    ago = _AGO.match(raw)
    if ago:
        hours = float(ago.group(1)) * {"h": 1, "d": 24, "w": 168}[ago.group(2)]
        return datetime.now(UTC) - timedelta(hours=hours)
    try:
        when = datetime.fromisoformat(raw.strip())
    except ValueError:
        raise ConfigError(field, raw, "a date or time (2026-11-25, 2026-11-25T08:00) or an "
                          "age (7d, 12h, 2w)") from None
    return when if when.tzinfo else when.astimezone()


def started_at(entry: Mapping[str, Any]) -> datetime | None:
    """When the run started (run.json's wall time), None if it does not say."""
    try:
        when = datetime.strptime(str(entry.get("started", "")), "%Y-%m-%dT%H:%M:%S%z")
    except ValueError:
        return None
    return when


def _values(value: object) -> list[str]:
    if value is None:
        return []
    if isinstance(value, str):
        return [value]
    if isinstance(value, Iterable):
        return [str(v) for v in value]
    return [str(value)]


def select_entries(entries: Iterable[Mapping[str, Any]], **filters: Any
                   ) -> list[dict[str, Any]]:
    """The entries that match every filter given: ``sample``, ``operator``, ``protocol``,
    ``status`` (each a value or a list of values, exact, case-insensitive; ``*`` and ``?``
    as wildcards), ``tag`` (each tag given must be on the run), ``since`` / ``until`` (see
    :func:`parse_when`). An unknown filter is a ConfigError naming it."""
    unknown = sorted(set(filters) - set(FILTERS) - {"tags"})
    if unknown:
        raise ConfigError(unknown[0], filters[unknown[0]], f"allowed filters: "
                          f"{', '.join(FILTERS)}")
    since = parse_when(filters["since"], "since") if filters.get("since") else None
    until = parse_when(filters["until"], "until") if filters.get("until") else None
    if until is not None and re.fullmatch(r"\d{4}-\d{2}-\d{2}", str(filters["until"])):
        until += timedelta(days=1)  # a date: the whole day
    tags = {t.lower() for t in _values(filters.get("tag")) + _values(filters.get("tags"))}
    wanted = {key: [re.compile(fnmatch_pattern(v), re.IGNORECASE) for v in _values(
        filters.get(key))] for key in ("sample", "operator", "protocol", "status")}
    out = []
    for entry in entries:
        if any(patterns and not any(p.fullmatch(str(entry.get(key, ""))) for p in patterns)
               for key, patterns in wanted.items()):
            continue
        if tags - {str(t).lower() for t in entry.get("tags", [])}:
            continue
        if since is not None or until is not None:
            when = started_at(entry)
            if when is None or (since is not None and when < since) or (
                    until is not None and when >= until):
                continue
        out.append(dict(entry))
    return out


def fnmatch_pattern(text: str) -> str:
    """``*`` and ``?`` as wildcards, everything else literal."""
    return "".join(".*" if c == "*" else "." if c == "?" else re.escape(c) for c in text)
