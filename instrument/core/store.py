"""Crash-safe run directories: metadata as JSON, each step's samples streamed to HDF5.

Layout of a run directory::

    run.json             rig, protocol, software version, instruments, times, status, steps,
                         interlock trips (rewritten atomically: write, fsync, rename)
    steps/NN_name.h5     one file per step: one 1-D dataset per column, units in attributes
    run.lock             the pid of the process recording into the directory (flock'd)

Each step file is written in HDF5's single-writer/multiple-reader (SWMR) mode and flushed at
least once a second of wall time, so a run killed at any moment (SIGKILL included) keeps
every flushed sample readable, and a live viewer can read while the run writes. A step file
closed normally opens with a plain ``h5py.File(path, "r")``; one left by a crash opens with
``swmr=True`` (``read_step`` does that), and ``seal_step`` rewrites it as a plain file.

Storage faults (ADR 0080): the first failed write of a step file (disk full, size limit, I/O
error) detaches the file from the disk and closes it once, keeping what was flushed, and
raises :class:`StorageFault`; run.json is still written (a space reserve is released first).
Readers trust nothing: :func:`check_metadata`, :meth:`RunDirectory.step_file` and
:func:`check_step_file` refuse crafted or damaged input with a ConfigError naming it.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import json
import math
import os
import re
import shutil
import stat
import struct
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import h5py
import numpy as np

from gelrig.instrument.core.arrays import FloatArray
from gelrig.instrument.core.errors import ConfigError, GelrigError
from gelrig.instrument.core.paths import check_out_dir as check_out_dir  # re-exported
from gelrig.instrument.core.paths import check_path as check_path
from gelrig.instrument.core.paths import existing_parent as existing_parent

try:
    import fcntl
except ImportError:  # Windows: the lock file records the holder but does not lock
    fcntl = None  # type: ignore[assignment]

#: Longest wall time (s) between flushes of a step file.
FLUSH_INTERVAL = 1.0
#: Rows buffered before a flush regardless of time.
FLUSH_ROWS = 200_000
_CHUNK = 16_384
#: Bytes kept free beside run.json, released when a write fails for lack of space.
RESERVE_BYTES = 256 * 1024
RESERVE_NAME = ".space-reserve"
LOCK_NAME = "run.lock"
#: Longest wall time (s) reading one step file may take.
READ_DEADLINE = 120.0
#: Largest run.json read (bytes).
MAX_METADATA_BYTES = 64 * 1024 * 1024
_READ_ROWS = 1 << 20
#: Most bytes of columns read whole into memory (read_step: gelrig analyze, the GUI's run
#: view): 2 GiB, e.g. 5.4e7 rows of the compression rig's 5 columns (15 h at 1 kHz).
MAX_READ_BYTES = 2 * 1024**3
#: Most rows a step column may declare: what a run may record (protocols/bounds.py's
#: MAX_RUN_SAMPLES).
MAX_STEP_ROWS = 1_000_000_000
#: Most bytes of one HDF5 chunk of a column: reading one row decompresses its whole chunk.
MAX_CHUNK_BYTES = 16 * 1024**2
#: Most a compressed column may expand over the bytes it stores: deflate's ceiling is about
#: 1032x; a larger ratio is a crafted file (a huge column of fill values).
MAX_COMPRESSION = 1100
_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_SPACE = {errno.ENOSPC: "disk full", errno.EFBIG: "file size limit reached",
          errno.EDQUOT: "disk quota exceeded"}


class StorageFault(GelrigError):
    """Writing the run directory failed (disk full, I/O error); what was flushed is kept."""


def _errno_of(exc: BaseException) -> int | None:
    """The errno of an OSError, or the one HDF5 names in its message."""
    if isinstance(exc, OSError) and exc.errno:
        return exc.errno
    match = re.search(r"errno = (\d+)", str(exc))
    return int(match.group(1)) if match else None


def describe_io_error(exc: BaseException) -> str:
    """'disk full', 'file size limit reached', 'I/O error (...)': what a user can act on."""
    code = _errno_of(exc)
    if code in _SPACE:
        return _SPACE[code]
    if code:
        return f"I/O error ({os.strerror(code)})"
    return f"I/O error ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"


def _write_replace(path: Path, tmp: Path, text: bytes) -> None:
    with tmp.open("wb") as handle:
        handle.write(text)
        handle.flush()
        os.fsync(handle.fileno())
    tmp.replace(path)


def _atomic_write_text(path: Path, text: str) -> None:
    """Write, fsync, rename; on a full disk release the reserve and retry, then rewrite in
    place if the text fits the file's blocks. Never leaves the temporary file behind, never
    a cut-off file; raises StorageFault if all fail (the file keeps its last whole text)."""
    tmp = path.with_name(path.name + ".tmp")
    data = text.encode()
    try:
        _write_replace(path, tmp, data)
        return
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        first = exc
    if _errno_of(first) in _SPACE:
        (path.parent / RESERVE_NAME).unlink(missing_ok=True)
        try:
            _write_replace(path, tmp, data)
            return
        except OSError:
            tmp.unlink(missing_ok=True)
        # in place, into the blocks it already has: only a text that fits them, so a write
        # that runs out of space mid-way can never leave a cut-off (invalid) run.json
        with contextlib.suppress(OSError):
            if len(data) <= path.stat().st_size:
                with path.open("r+b") as handle:
                    handle.write(data)
                    handle.truncate()
                    handle.flush()
                    os.fsync(handle.fileno())
                return
    raise StorageFault(f"{describe_io_error(first)} writing {path.name}") from None


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "step"


def _detach(handle: h5py.File, fd: int | None) -> None:
    """Close an HDF5 file whose writes failed, exactly once and without touching the disk
    again: its descriptor ``fd`` (taken while the file was sound: asking a failed handle for
    it can crash the interpreter) is pointed at /dev/null first, so the close's final flush
    cannot fail (a file left half-closed makes HDF5 crash the interpreter at exit)."""
    if fd is not None:
        with contextlib.suppress(OSError):
            null = os.open(os.devnull, os.O_RDWR)
            os.dup2(null, fd)
            os.close(null)
    with contextlib.suppress(Exception):
        handle.close()


#: The step file's ``status`` attribute: created when the file is, set in place on close.
STATUS_DTYPE = h5py.string_dtype("utf-8", 32)


class StepWriter:
    """Appends blocks of columns to one step's HDF5 file; flushes at least every second.

    The first failed write (disk full, I/O error) detaches and closes the file, keeping what
    was flushed, sets :attr:`dead` to one line for the user and raises StorageFault; every
    later call raises it again without touching the file.
    """

    def __init__(self, path: Path, columns: Mapping[str, str], attrs: Mapping[str, Any]):
        self.path = path
        self.columns = dict(columns)
        self.rows = 0
        self.dead: str | None = None
        self._file: h5py.File | None = None
        self._buffer: dict[str, list[FloatArray]] = {name: [] for name in self.columns}
        self._buffered = 0
        self._datasets: dict[str, h5py.Dataset] = {}
        self._fd: int | None = None
        try:
            self._file = h5py.File(path, "w", libver="latest")
            self._fd = int(self._file.id.get_vfd_handle())
            self._file.attrs.create("status", np.array(b"running", STATUS_DTYPE))
            for key, value in attrs.items():
                self._file.attrs[key] = (json.dumps(value) if isinstance(value, dict | list)
                                         else value)
            self._file.attrs["columns"] = json.dumps(list(self.columns))
            for name, unit in self.columns.items():
                ds = self._file.create_dataset(
                    name, shape=(0,), maxshape=(None,), chunks=(_CHUNK,), dtype="f8"
                )
                ds.attrs["unit"] = unit
                self._datasets[name] = ds
            self._file.swmr_mode = True
        except (OSError, RuntimeError) as exc:
            self._die(exc)
        self._last_flush = time.monotonic()

    @property
    def label(self) -> str:
        """The file as named in run.json (``steps/NN_name.h5``)."""
        return f"{self.path.parent.name}/{self.path.name}"

    def _die(self, exc: BaseException) -> NoReturn:
        if self._file is not None:
            _detach(self._file, self._fd)
        self._file = None
        self._datasets = {}
        self._buffer = {name: [] for name in self.columns}
        self._buffered = 0
        with contextlib.suppress(Exception):  # count what a reader will find
            kept = read_step(self.path)
            self.rows = min((v.size for v in kept.values()), default=0)
        self.dead = f"{describe_io_error(exc)} writing {self.label}: {self.rows:,} samples kept"
        raise StorageFault(self.dead) from None

    def append(self, data: Mapping[str, FloatArray]) -> None:
        """Buffer one block (every column, equal lengths); flush when due."""
        if self.dead:
            raise StorageFault(self.dead)
        lengths = {len(np.atleast_1d(data[name])) for name in self.columns if name in data}
        missing = [name for name in self.columns if name not in data]
        if missing or len(lengths) != 1:
            raise ValueError(f"block must hold every column with equal lengths: {list(data)}")
        for name in self.columns:
            self._buffer[name].append(np.atleast_1d(np.asarray(data[name], dtype=float)))
        self._buffered += lengths.pop()
        if self._buffered >= FLUSH_ROWS or time.monotonic() - self._last_flush >= FLUSH_INTERVAL:
            self.flush()

    def flush(self) -> None:
        """Write the buffer and make it durable for readers."""
        if self.dead or self._file is None:
            raise StorageFault(self.dead or f"{self.label} is closed")
        try:
            if self._buffered:
                start, stop = self.rows, self.rows + self._buffered
                for name, ds in self._datasets.items():
                    ds.resize((stop,))
                    ds[start:stop] = np.concatenate(self._buffer[name])
                    self._buffer[name] = []
                    ds.flush()
                self.rows = stop
                self._buffered = 0
            self._file.flush()
        except (OSError, RuntimeError) as exc:
            self._die(exc)
        self._last_flush = time.monotonic()

    def close(self, status: str | None = None) -> None:
        """Set the ``status`` attribute (at most 32 bytes of UTF-8), flush and close; the file
        then opens without SWMR. Does nothing once dead.

        The status is written in place while the file is still open for SWMR writing (the
        attribute exists since the file does), so a full disk at the close cannot leave the
        file flagged as open by a plain writer, which no reader can open: reopening it
        read-write to add attributes did that, and crashed the interpreter (exit 139).
        """
        if self.dead or self._file is None or not self._file.id.valid:
            return
        self.flush()
        try:
            if status is not None:
                value = status.encode()[:32].decode(errors="ignore")  # whole characters
                self._file.attrs.modify("status", np.array(value.encode(), STATUS_DTYPE))
            self._file.close()
            self._file = None
        except (OSError, RuntimeError) as exc:
            self._die(exc)


@dataclass
class StepRecord:
    """One step's entry in run.json."""

    index: int
    name: str
    kind: str
    status: str
    file: str
    samples: int = 0
    started: float | None = None
    finished: float | None = None
    results: dict[str, Any] | None = None
    #: the step's parameters (TOML keys, SI values): a script's steps are known only here
    params: dict[str, Any] | None = None


class RunDirectory:
    """A run's folder: metadata in run.json, samples in steps/*.h5."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.meta_path = self.path / "run.json"

    @classmethod
    def create(cls, path: str | Path, metadata: Mapping[str, Any]) -> RunDirectory:
        """A new run directory in a new or empty folder (ConfigError otherwise)."""
        run = cls(path)
        check_out_dir(run.path)
        try:
            (run.path / "steps").mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError("--out", str(run.path), f"cannot be created ({exc.strerror})"
                              ) from None
        meta = dict(metadata)
        meta.setdefault("status", "created")
        meta.setdefault("steps", [])
        meta.setdefault("interlock_trips", [])
        meta.setdefault("created", time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        run.write_metadata(meta)
        run.reserve_space()
        return run

    def reserve_space(self) -> None:
        """Keep RESERVE_BYTES aside so that run.json's final status fits on a full disk."""
        path = self.path / RESERVE_NAME
        with contextlib.suppress(OSError):
            if not path.exists() or path.stat().st_size < RESERVE_BYTES:
                with path.open("wb") as handle:
                    handle.write(b"\0" * RESERVE_BYTES)
                    handle.flush()
                    os.fsync(handle.fileno())

    def release_space(self) -> None:
        """Remove the reserve (the run has ended)."""
        with contextlib.suppress(OSError):
            (self.path / RESERVE_NAME).unlink(missing_ok=True)

    def discard_empty(self, also: Sequence[str] = ()) -> None:
        """Remove a run directory that never recorded a step (only what create made, and the
        files named in ``also``, such as the run's log)."""
        with contextlib.suppress(OSError):
            if any((self.path / "steps").iterdir()):
                return
            for name in ("run.json", RESERVE_NAME, LOCK_NAME, *also):
                (self.path / name).unlink(missing_ok=True)
            (self.path / "steps").rmdir()
            self.path.rmdir()

    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """Hold the run directory for this process (run, resume); a second holder gets a
        ConfigError naming the process that has it."""
        path = self.path / LOCK_NAME
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise ConfigError("run", str(self.path), f"cannot be locked ({exc.strerror})"
                              ) from None
        try:
            if fcntl is not None:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError:
                    holder = os.pread(fd, 200, 0).decode(errors="replace").strip()
                    raise ConfigError("run", str(self.path), f"is in use by "
                                      f"{holder or 'another process'}; wait until it ends "
                                      "or stop it") from None
            command = " ".join(Path(a).name if i == 0 else a for i, a in enumerate(sys.argv[:2]))
            note = (f"process {os.getpid()} ({command}) since "
                    f"{time.strftime('%Y-%m-%dT%H:%M:%S%z')}").encode()
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)
                os.pwrite(fd, note, 0)
            yield
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)
        finally:
            os.close(fd)  # releases the flock

    def read_metadata(self) -> dict[str, Any]:
        """run.json, checked against its schema (ConfigError naming what is wrong)."""
        source = str(self.meta_path)
        try:
            info = os.stat(self.meta_path)
        except FileNotFoundError:
            allowed = "is not a run directory (no run.json)"
            raise ConfigError("run", str(self.path), allowed) from None
        except OSError as exc:
            raise ConfigError("run.json", source, f"cannot be read ({exc.strerror})") from None
        if not stat.S_ISREG(info.st_mode):
            raise ConfigError("run.json", source, f"is {_kind_of(info.st_mode)}, not a file")
        if info.st_size > MAX_METADATA_BYTES:
            raise ConfigError("run.json", source, f"holds {info.st_size:,} bytes; a run's "
                              f"metadata is at most {MAX_METADATA_BYTES:,}")
        try:
            with self.meta_path.open("rb") as handle:
                text = handle.read(MAX_METADATA_BYTES + 1).decode("utf-8")
            raw = json.loads(text)
        except UnicodeDecodeError as exc:
            raise ConfigError("run.json", source, f"is not UTF-8 text ({exc.reason} at byte "
                              f"{exc.start})") from None
        except json.JSONDecodeError as exc:
            raise ConfigError("run.json", source, f"is not valid JSON ({exc})") from None
        except RecursionError:
            raise ConfigError("run.json", source, "is nested too deeply to be a run's "
                              "metadata") from None
        except OSError as exc:
            raise ConfigError("run.json", source, f"cannot be read ({exc.strerror})") from None
        return check_metadata(raw, source)

    def write_metadata(self, meta: Mapping[str, Any]) -> None:
        _atomic_write_text(self.meta_path, json.dumps(meta, indent=2, default=_jsonable))

    def update(self, **changes: Any) -> dict[str, Any]:
        meta = self.read_metadata()
        meta.update(changes)
        self.write_metadata(meta)
        return meta

    def step_path(self, index: int, name: str) -> Path:
        return self.path / "steps" / f"{index:02d}_{_slug(name)}.h5"

    def open_step(
        self, index: int, name: str, kind: str, columns: Mapping[str, str],
        params: Mapping[str, Any], t_start: float,
    ) -> StepWriter:
        path = self.step_path(index, name)
        writer = StepWriter(path, columns, {"name": name, "kind": kind, "index": index,
                                            "params": dict(params)})
        meta = self.read_metadata()
        steps = [s for s in meta["steps"] if s["index"] != index]
        steps.append(StepRecord(index, name, kind, "running", str(path.relative_to(self.path)),
                                started=t_start, params=dict(params)).__dict__)
        meta["steps"] = sorted(steps, key=lambda s: s["index"])
        self.write_metadata(meta)
        return writer

    def finish_step(
        self, index: int, status: str, samples: int, t_end: float, results: Mapping[str, Any]
    ) -> None:
        meta = self.read_metadata()
        for step in meta["steps"]:
            if step["index"] == index:
                step.update(status=status, samples=samples, finished=t_end,
                            results=dict(results))
        self.write_metadata(meta)

    def completed_steps(self) -> dict[int, dict[str, Any]]:
        """Index -> record of every step that completed (what a resume skips)."""
        return {s["index"]: s for s in self.read_metadata()["steps"] if s["status"] == "completed"}

    def step_file(self, record: Mapping[str, Any]) -> Path:
        """A step record's file, refused unless it is a relative path inside the run
        directory (after following symlinks). It may be missing; see check_step_file."""
        rel = str(record.get("file", ""))
        where = f"step {record.get('index')} file"
        parts = Path(rel).parts
        if not rel or Path(rel).is_absolute() or ".." in parts:
            raise ConfigError(where, rel, "must be a relative path inside the run directory",
                              str(self.meta_path))
        path = self.path / rel
        target = path.resolve()
        if not target.is_relative_to(self.path.resolve()):
            raise ConfigError(where, rel, f"leads outside the run directory (to {target})",
                              str(self.meta_path))
        return path

    def archive_incomplete(self) -> list[str]:
        """Before a resume: seal every step file a crash left open and keep it under a new
        name (``NN_name.attempt-K.h5``), listed in ``interrupted_steps``; nothing is lost.
        An attempt a crash ended before run.json said so gets its ``samples`` and
        ``finished`` (its last sample's time) from the file: the resume's clock goes on
        from there (one time base per run: the attempt's samples stay before the resumed
        step's)."""
        meta = self.read_metadata()
        kept, archived = [], []
        for step in meta["steps"]:
            if step["status"] == "completed":
                kept.append(step)
                continue
            path = self.step_file(step)
            if path.exists():
                check_step_file(path)
                seal_step(path)
                k = 1
                while (target := path.with_name(f"{path.stem}.attempt-{k}.h5")).exists():
                    k += 1
                path.replace(target)
                step = {**step, "file": str(target.relative_to(self.path))}
                rows, last = step_extent(target)
                if step.get("finished") is None and last is not None:
                    step["finished"] = last
                step["samples"] = max(int(step.get("samples") or 0), rows)
            step["status"] = "interrupted" if step["status"] == "running" else step["status"]
            archived.append(step)
        meta["steps"] = kept
        meta.setdefault("interrupted_steps", []).extend(archived)
        self.write_metadata(meta)
        return [s["file"] for s in archived]

    def copy_to(self, path: str | Path) -> RunDirectory:
        """A copy of this run in a new or empty folder (another disk): run.json and every
        step file it names, so that the copy can be resumed there."""
        meta = self.read_metadata()
        target = RunDirectory(path)
        check_out_dir(target.path)
        try:
            (target.path / "steps").mkdir(parents=True, exist_ok=True)
            for record in [*meta["steps"], *meta.get("interrupted_steps", [])]:
                source = self.step_file(record)
                if source.exists():
                    check_step_file(source)
                    dest = target.path / record["file"]
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(source, dest)
        except OSError as exc:
            raise StorageFault(f"{describe_io_error(exc)} copying {self.path} to "
                               f"{target.path}") from None
        meta["copied_from"] = [*meta.get("copied_from", []), str(self.path.resolve())]
        target.write_metadata(meta)
        target.reserve_space()
        return target

    def read_step(self, index: int) -> dict[str, FloatArray]:
        """Columns of one step (also from a file left open by a crash)."""
        for step in self.read_metadata()["steps"]:
            if step["index"] == index:
                return read_step(self.step_file(step))
        raise ConfigError("step", index, f"not in {self.meta_path}")


def _jsonable(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


# -- checking what is read -------------------------------------------------------------------

_Spec = dict[str, tuple[type | tuple[type, ...], str]]
_RECORD: _Spec = {"index": (int, "an integer"), "name": (str, "a string"),
                  "kind": (str, "a string"), "status": (str, "a string"),
                  "file": (str, "a string (a path inside the run directory)")}
_OPTIONAL: _Spec = {"samples": (int, "an integer"), "started": ((int, float), "a number"),
                    "finished": ((int, float), "a number"), "results": (dict, "an object")}
_TOP: _Spec = {"status": (str, "a string"), "protocol": (dict, "an object"),
               "rig": (dict, "an object"), "interlock_trips": (list, "a list"),
               "faults": (list, "a list")}


def _type_name(value: object) -> str:
    names = {dict: "an object", list: "a list", str: "a string", int: "an integer",
             float: "a number", bool: "true/false", type(None): "null"}
    return names.get(type(value), type(value).__name__)


def _is(value: object, types: type | tuple[type, ...]) -> bool:
    allowed = types if isinstance(types, tuple) else (types,)
    return isinstance(value, allowed) and (bool in allowed or not isinstance(value, bool))


def _check_fields(record: Mapping[str, Any], spec: _Spec, prefix: str, source: str,
                  required: bool) -> None:
    for key, (types, wanted) in spec.items():
        value = record.get(key)
        if value is None and not required:
            continue
        if not _is(value, types):
            raise ConfigError(f"{prefix}{key}", "missing" if key not in record else value,
                              f"must be {wanted}", source)


def check_metadata(meta: object, source: str = "run.json") -> dict[str, Any]:
    """run.json's content checked: an object with a ``steps`` list of step records, each
    with an integer ``index`` and string ``name``, ``kind``, ``status`` and ``file``."""
    if not isinstance(meta, dict):
        raise ConfigError("run.json", _type_name(meta), "must be a JSON object with the "
                          "run's metadata and a steps list", source)
    if "steps" not in meta:
        raise ConfigError("steps", "missing", "run.json must list the run's steps", source)
    _check_fields(meta, _TOP, "", source, required=False)
    for group in ("steps", "interrupted_steps"):
        records = meta.get(group, [])
        if not isinstance(records, list):
            raise ConfigError(group, records, "must be a list of step records", source)
        for i, record in enumerate(records):
            if not isinstance(record, dict):
                raise ConfigError(f"{group}[{i}]", record, "must be an object (a step record)",
                                  source)
            _check_fields(record, _RECORD, f"{group}[{i}].", source, required=True)
            _check_fields(record, _OPTIONAL, f"{group}[{i}].", source, required=False)
            if record["index"] < 0:
                raise ConfigError(f"{group}[{i}].index", record["index"], "must be >= 0", source)
    return meta


def _kind_of(mode: int) -> str:
    for test, name in ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISDIR, "a folder")):
        if test(mode):
            return name
    return "not a regular file"


def check_step_file(path: Path) -> int:
    """Refuse anything but a whole HDF5 file before HDF5 opens it: a regular file (no FIFO,
    no device), the HDF5 signature, and no shorter than its superblock says. Returns its
    size in bytes."""
    source = str(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise ConfigError("step file", source, "is missing") from None
    except OSError as exc:
        raise ConfigError("step file", source, f"cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError("step file", source, f"is {_kind_of(info.st_mode)}; a step file is a "
                          "regular HDF5 file")
    size = info.st_size
    try:
        with path.open("rb") as handle:
            head = handle.read(64)
    except OSError as exc:
        raise ConfigError("step file", source, f"cannot be read ({exc.strerror})") from None
    if not head.startswith(_SIGNATURE):
        raise ConfigError("step file", source, f"is not an HDF5 file ({size:,} bytes without "
                          "the HDF5 signature)")
    version = head[8]
    if version in (2, 3) and len(head) >= 36 and head[9] == 8:  # 8-byte addresses
        declared = struct.unpack("<Q", head[28:36])[0]
        if declared > size:
            raise ConfigError("step file", source, f"is truncated: {size:,} of the "
                              f"{declared:,} bytes its header declares (damaged copy?)")
    return size


@functools.cache
def _swmr_fapl() -> h5py.h5p.PropFAID:
    """File access for reading files left open by a writer, with few metadata read retries:
    HDF5's default for SWMR readers (100, with a growing back-off) hangs on damaged files."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_fclose_degree(h5py.h5f.CLOSE_STRONG)
    with contextlib.suppress(Exception):
        lib = next(line.split()[-1] for line in Path("/proc/self/maps").read_text().splitlines()
                   if "libhdf5" in line.rsplit("/", 1)[-1] and "_hl" not in line)
        setter = ctypes.CDLL(lib).H5Pset_metadata_read_attempts
        setter.argtypes = [ctypes.c_int64, ctypes.c_uint]
        setter(fapl.id, 10)
    return fapl


def _open_readable(path: Path) -> tuple[h5py.File, bool]:
    """The file opened for reading, and whether a crash left it open for writing (then it is
    opened as a SWMR reader)."""
    try:
        return h5py.File(path, "r"), False
    except OSError:  # left open for writing by a crash
        fid = h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ,
                            fapl=_swmr_fapl())
        return h5py.File(fid), True


def _damaged(path: Path, exc: BaseException) -> ConfigError:
    first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return ConfigError("step file", str(path), f"cannot be read as HDF5 ({first})")


def _links(handle: h5py.File, path: Path) -> list[str]:
    """The names of the file's top-level objects, refusing any link that is not the object
    itself: a soft link (another name in the file) or an external link (another file)."""
    names = []
    for name in handle:
        link = handle.get(name, getlink=True)
        if isinstance(link, h5py.ExternalLink):
            raise ConfigError(f"column {name}", f"{link.filename}:{link.path}", "is an "
                              "external link to another file; a step file holds its columns "
                              "itself (crafted)", str(path))
        if isinstance(link, h5py.SoftLink):
            raise ConfigError(f"column {name}", link.path, "is a soft link; a step file holds "
                              "each column once, under its own name (crafted)", str(path))
        names.append(name)
    return names


def _check_column(name: str, ds: h5py.Dataset, path: Path, size: int) -> None:
    """One column checked from its HDF5 metadata before any of it is read: where its data
    lives (in this file: no external raw storage, no virtual dataset), its shape and type,
    and its declared size against what it stores (a compressed column expands at most
    MAX_COMPRESSION times) and the bounds."""
    source = str(path)
    dcpl = ds.id.get_create_plist()
    if dcpl.get_layout() == h5py.h5d.VIRTUAL:
        raise ConfigError(f"column {name}", "virtual dataset", "reads its data from other "
                          "files; a step column is stored in the step file (crafted)", source)
    if dcpl.get_external_count():
        target = os.fsdecode(dcpl.get_external(0)[0])
        raise ConfigError(f"column {name}", target, "is external raw storage (the column's "
                          "data would be read from that file); a step column is stored in the "
                          "step file (crafted)", source)
    if ds.ndim != 1 or ds.dtype.kind not in "fiub":
        raise ConfigError(f"column {name}", f"{ds.dtype} {ds.shape}", "a step column is "
                          "a 1-D array of numbers", source)
    rows = ds.shape[0]
    nbytes = rows * ds.dtype.itemsize
    if rows > MAX_STEP_ROWS:
        raise ConfigError(f"column {name}", f"{rows:,} rows", f"declares more than a run "
                          f"records (at most {MAX_STEP_ROWS:,} rows; damaged or crafted)", source)
    if ds.chunks is not None:
        chunk = math.prod(ds.chunks) * ds.dtype.itemsize
        if chunk > MAX_CHUNK_BYTES:
            raise ConfigError(f"column {name}", f"chunks of {chunk:,} bytes", f"at most "
                              f"{MAX_CHUNK_BYTES:,} bytes a chunk (reading one row "
                              "decompresses its whole chunk)", source)
    if dcpl.get_nfilters():  # compressed: the bytes it stores bound what it may hold
        stored = ds.id.get_storage_size()
        if nbytes > stored * MAX_COMPRESSION:
            raise ConfigError(f"column {name}", f"{rows:,} rows", f"declares {nbytes:,} "
                              f"bytes of {ds.dtype} stored in {stored:,} compressed bytes; "
                              f"a column expands at most {MAX_COMPRESSION}x (crafted)", source)
    elif nbytes > size:
        raise ConfigError(f"column {name}", f"{rows:,} rows", f"declares {nbytes:,} bytes of "
                          f"{ds.dtype} in a file of {size:,} bytes (damaged or crafted)", source)


def _columns(handle: h5py.File, path: Path, size: int, columns: Sequence[str] | None
             ) -> dict[str, h5py.Dataset]:
    """The step's datasets, each checked (:func:`_check_column`)."""
    names = _links(handle, path)
    stored = [k for k in names if handle.get(k, getclass=True) is h5py.Dataset]
    try:
        order = json.loads(handle.attrs.get("columns", "[]"))
    except (TypeError, ValueError):
        order = []
    order = [k for k in order if isinstance(k, str)] if isinstance(order, list) else []
    wanted = list(columns or [k for k in order if k in stored] or stored)
    out = {}
    for name in wanted:
        if name not in stored:
            raise ConfigError(f"column {name}", "missing", "not in this step file", str(path))
        ds = handle[name]
        _check_column(name, ds, path, size)
        out[name] = ds
    return out


class StepColumns:
    """An open step file's checked columns, read in chunks of rows: the memory a reader
    needs is one chunk, whatever the file declares."""

    def __init__(self, path: Path, handle: h5py.File, datasets: Mapping[str, h5py.Dataset],
                 rows: int, deadline: float):
        self.path = path
        #: the file's attributes (name, kind, index, params, columns)
        self.attrs = handle.attrs
        self.datasets = dict(datasets)
        #: rows every column has
        self.rows = rows
        self.deadline = deadline
        self._spent = 0.0

    @property
    def names(self) -> list[str]:
        return list(self.datasets)

    def chunks(self, rows: int = _READ_ROWS) -> Iterator[dict[str, FloatArray]]:
        """Every row, ``rows`` at a time, as float columns. The time spent reading (not the
        caller's time between chunks) is bounded by the deadline."""
        for start in range(0, self.rows, rows):
            stop = min(self.rows, start + rows)
            began = time.monotonic()
            try:
                block = {name: np.asarray(ds[start:stop], dtype=float)
                         for name, ds in self.datasets.items()}
            except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
                raise _damaged(self.path, exc) from None
            self._spent += time.monotonic() - began
            if self._spent > self.deadline:
                raise ConfigError("step file", str(self.path), f"could not be read within "
                                  f"{self.deadline:g} s (a damaged file or a stalled disk)")
            yield block


@contextlib.contextmanager
def open_step(path: str | Path, columns: Sequence[str] | None = None,
              deadline: float = READ_DEADLINE) -> Iterator[StepColumns]:
    """Open a step file for reading in chunks, every check made first: the file
    (:func:`check_step_file`), then every column's metadata (:func:`_check_column`), and
    their lengths: equal, except in a file a crash left open for writing (its columns are
    flushed one after another: a row exists once all have it). Anything damaged or crafted
    is a ConfigError naming the file, the column and what is allowed."""
    path = Path(path)
    size = check_step_file(path)
    try:
        handle, crashed = _open_readable(path)
    except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
        raise _damaged(path, exc) from None
    with handle:
        try:
            datasets = _columns(handle, path, size, columns)
            lengths = {name: ds.shape[0] for name, ds in datasets.items()}
        except ConfigError:
            raise
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
            raise _damaged(path, exc) from None
        rows = min(lengths.values(), default=0)
        longest = max(lengths, key=lengths.__getitem__, default="")
        if not crashed and longest and lengths[longest] != rows:
            shortest = min(lengths, key=lengths.__getitem__)
            raise ConfigError(f"column {longest}", f"{lengths[longest]:,} rows", f"column "
                              f"{shortest} has {rows:,}; the columns of a closed step file "
                              "have equal lengths (damaged or crafted)", str(path))
        yield StepColumns(path, handle, datasets, rows, deadline)


def read_step(path: str | Path, columns: Sequence[str] | None = None,
              deadline: float = READ_DEADLINE) -> dict[str, FloatArray]:
    """Read a step file's columns whole; works on files a crash left in SWMR-write state.

    Checked as :func:`open_step` says, and refused before anything is allocated when the
    columns would take more than MAX_READ_BYTES as floats (``gelrig export`` streams any
    size); read in bounded chunks within ``deadline`` seconds of reading.
    """
    with open_step(path, columns, deadline) as step:
        need = step.rows * 8 * len(step.datasets)
        if need > MAX_READ_BYTES:
            raise ConfigError("step file", str(step.path), f"holds {step.rows:,} rows x "
                              f"{len(step.datasets)} columns ({need / 2**30:.1f} GiB as "
                              f"floats); at most {MAX_READ_BYTES / 2**30:g} GiB are read whole "
                              "(gelrig export streams any size)")
        out = {name: np.empty(step.rows, dtype=float) for name in step.datasets}
        at = 0
        for block in step.chunks():
            n = len(next(iter(block.values())))
            for name, values in block.items():
                out[name][at:at + n] = values
            at += n
        return out


def step_extent(path: str | Path) -> tuple[int, float | None]:
    """Rows of a step file and the time (``t_s``) of its last one (None: no rows, or no
    ``t_s`` column); checked like every read (:func:`open_step`), one value read."""
    with open_step(path) as step:
        column = step.datasets.get("t_s")
        if column is None or not step.rows:
            return step.rows, None
        try:
            return step.rows, float(column[step.rows - 1])
        except (OSError, RuntimeError, ValueError, TypeError) as exc:
            raise _damaged(step.path, exc) from None


def seal_step(path: str | Path) -> bool:
    """Rewrite a step file left by a crash as a plain HDF5 file; True if it needed it. Its
    columns are checked (:func:`open_step`), copied in chunks and cut to the rows every
    column has. On failure (disk full) the partial copy is removed and StorageFault raised."""
    path = Path(path)
    try:
        h5py.File(path, "r").close()
        return False
    except OSError:
        pass
    tmp = path.with_name(path.name + ".sealing")
    try:
        with open_step(path) as step, h5py.File(tmp, "w") as dst:
            for key, value in step.attrs.items():
                dst.attrs[key] = value
            out = {}
            for name, ds in step.datasets.items():
                out[name] = dst.create_dataset(name, shape=(step.rows,), dtype=ds.dtype,
                                               chunks=(_CHUNK,), maxshape=(None,))
                for key, value in ds.attrs.items():
                    out[name].attrs[key] = value
            at = 0
            for block in step.chunks():
                n = len(next(iter(block.values()), ()))
                for name, values in block.items():
                    out[name][at:at + n] = values
                at += n
            dst.attrs["sealed_after_crash"] = True
    except ConfigError:
        tmp.unlink(missing_ok=True)
        raise
    except (OSError, RuntimeError) as exc:
        tmp.unlink(missing_ok=True)
        raise StorageFault(f"{describe_io_error(exc)} sealing {path.parent.name}/{path.name}; "
                           "free space, or resume into another folder with --out") from None
    tmp.replace(path)
    return True
