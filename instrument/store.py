"""Crash-safe run directories: metadata as JSON, each step's samples streamed to HDF5.

Layout of a run directory::

    run.json             rig, protocol, software version, instruments, times, status, steps,
                         interlock trips (rewritten atomically: write, fsync, rename)
    steps/NN_name.h5     one file per step: one 1-D dataset per column, units in attributes

Each step file is written in HDF5's single-writer/multiple-reader (SWMR) mode and flushed at
least once a second of wall time, so a run killed at any moment (SIGKILL included) keeps
every flushed sample readable, and a live viewer can read while the run writes. A step file
closed normally opens with a plain ``h5py.File(path, "r")``; one left by a crash opens with
``swmr=True`` (``read_step`` does that), and ``seal_step`` rewrites it as a plain file.
"""

from __future__ import annotations

import json
import os
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from instrument.contact import FloatArray
from instrument.errors import ConfigError

#: Longest wall time (s) between flushes of a step file.
FLUSH_INTERVAL = 1.0
#: Rows buffered before a flush regardless of time.
FLUSH_ROWS = 200_000
_CHUNK = 16_384


def _atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w") as handle:
        handle.write(text)
        handle.flush()
        os.fsync(handle.fileno())
    tmp.replace(path)


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "step"


class StepWriter:
    """Appends blocks of columns to one step's HDF5 file; flushes at least every second."""

    def __init__(self, path: Path, columns: Mapping[str, str], attrs: Mapping[str, Any]):
        self.path = path
        self.columns = dict(columns)
        self._file = h5py.File(path, "w", libver="latest")
        for key, value in attrs.items():
            self._file.attrs[key] = json.dumps(value) if isinstance(value, dict | list) else value
        self._file.attrs["columns"] = json.dumps(list(self.columns))
        self._datasets = {}
        for name, unit in self.columns.items():
            ds = self._file.create_dataset(
                name, shape=(0,), maxshape=(None,), chunks=(_CHUNK,), dtype="f8"
            )
            ds.attrs["unit"] = unit
            self._datasets[name] = ds
        self._file.swmr_mode = True
        self._buffer: dict[str, list[FloatArray]] = {name: [] for name in self.columns}
        self._buffered = 0
        self.rows = 0
        self._last_flush = time.monotonic()

    def append(self, data: Mapping[str, FloatArray]) -> None:
        """Buffer one block (every column, equal lengths); flush when due."""
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
        self._last_flush = time.monotonic()

    def close(self, attrs: Mapping[str, Any] | None = None) -> None:
        """Flush and close; the file then opens without SWMR."""
        if not self._file.id.valid:
            return
        self.flush()
        self._file.close()
        if attrs:
            with h5py.File(self.path, "r+") as handle:
                for key, value in attrs.items():
                    handle.attrs[key] = (
                        json.dumps(value) if isinstance(value, dict | list) else value
                    )


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


class RunDirectory:
    """A run's folder: metadata in run.json, samples in steps/*.h5."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.meta_path = self.path / "run.json"

    @classmethod
    def create(cls, path: str | Path, metadata: Mapping[str, Any]) -> RunDirectory:
        run = cls(path)
        if run.meta_path.exists():
            raise ConfigError("--out", str(run.path), "already holds a run; choose a new folder")
        (run.path / "steps").mkdir(parents=True, exist_ok=True)
        meta = dict(metadata)
        meta.setdefault("status", "created")
        meta.setdefault("steps", [])
        meta.setdefault("interlock_trips", [])
        meta.setdefault("created", time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        run.write_metadata(meta)
        return run

    def read_metadata(self) -> dict[str, Any]:
        try:
            meta: dict[str, Any] = json.loads(self.meta_path.read_text())
        except FileNotFoundError:
            allowed = "is not a run directory (no run.json)"
            raise ConfigError("run", str(self.path), allowed) from None
        except json.JSONDecodeError as exc:
            allowed = f"is not valid JSON ({exc})"
            raise ConfigError("run.json", str(self.meta_path), allowed) from None
        return meta

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
                                started=t_start).__dict__)
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

    def archive_incomplete(self) -> list[str]:
        """Before a resume: seal every step file a crash left open and keep it under a new
        name (``NN_name.attempt-K.h5``), listed in ``interrupted_steps``; nothing is lost."""
        meta = self.read_metadata()
        kept, archived = [], []
        for step in meta["steps"]:
            if step["status"] == "completed":
                kept.append(step)
                continue
            path = self.path / step["file"]
            if path.exists():
                seal_step(path)
                k = 1
                while (target := path.with_name(f"{path.stem}.attempt-{k}.h5")).exists():
                    k += 1
                path.replace(target)
                step = {**step, "file": str(target.relative_to(self.path))}
            step["status"] = "interrupted" if step["status"] == "running" else step["status"]
            archived.append(step)
        meta["steps"] = kept
        meta.setdefault("interrupted_steps", []).extend(archived)
        self.write_metadata(meta)
        return [s["file"] for s in archived]

    def read_step(self, index: int) -> dict[str, FloatArray]:
        """Columns of one step (also from a file left open by a crash)."""
        for step in self.read_metadata()["steps"]:
            if step["index"] == index:
                return read_step(self.path / step["file"])
        raise ConfigError("step", index, f"not in {self.meta_path}")


def _jsonable(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _open_readable(path: Path) -> h5py.File:
    try:
        return h5py.File(path, "r")
    except OSError:
        return h5py.File(path, "r", swmr=True)  # left open for writing by a crash


def read_step(path: str | Path, columns: Sequence[str] | None = None) -> dict[str, FloatArray]:
    """Read a step file's columns; works on files a crash left in SWMR-write state."""
    path = Path(path)
    if not path.exists():
        raise ConfigError("step file", str(path), "is missing")
    with _open_readable(path) as handle:
        stored = [k for k in handle if isinstance(handle[k], h5py.Dataset)]
        order = json.loads(handle.attrs.get("columns", "[]"))
        names = list(columns or [k for k in order if k in stored] or stored)
        # Columns are flushed one after another: a reader during writing, or a file killed
        # between two flushes, sees some longer than others. A row exists once all have it.
        rows = min((handle[name].shape[0] for name in names), default=0)
        return {name: np.asarray(handle[name][:rows], dtype=float) for name in names}


def seal_step(path: str | Path) -> bool:
    """Rewrite a step file left by a crash as a plain HDF5 file; True if it needed it."""
    path = Path(path)
    try:
        h5py.File(path, "r").close()
        return False
    except OSError:
        pass
    tmp = path.with_name(path.name + ".sealing")
    with h5py.File(path, "r", swmr=True) as src, h5py.File(tmp, "w") as dst:
        for key, value in src.attrs.items():
            dst.attrs[key] = value
        for name in src:
            ds = src[name]
            out = dst.create_dataset(name, data=ds[:], chunks=True, maxshape=(None,))
            for key, value in ds.attrs.items():
                out.attrs[key] = value
        dst.attrs["sealed_after_crash"] = True
    tmp.replace(path)
    return True
