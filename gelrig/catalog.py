"""Runs found and read from Python: :func:`runs` (the catalog as a DataFrame) and
:func:`load_run` (a run's steps as arrays with units), ADR 0370.

From "all holds of sample gel-A1" to a plot (pandas holds the table)::

    holds = gelrig.runs("runs", sample="gel-A1", protocol="*hold*")
    for path in holds.path:
        hold = gelrig.load_run(path).steps["ramp and hold"]
        plt.plot(hold["t_s"], hold["force_N"])
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gelrig.instrument.core.catalog import catalog_entries, select_entries, summarise_run
from gelrig.instrument.core.errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from gelrig.instrument.core.arrays import FloatArray

#: The catalog's columns a :func:`runs` table starts with, in order.
COLUMNS = ("path", "name", "sample", "operator", "protocol", "rig", "status", "started",
           "finished", "clock", "tags", "note", "reason")


def result_key(step_name: str, quantity: str) -> str:
    """The column (DataFrame) or key (``--json``) of one result: ``ramp and hold/1-term G_e``."""
    return f"{step_name}/{quantity}"


def flat_results(entry: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """A catalog entry's step results by :func:`result_key`: value, stderr, lo, hi, unit."""
    out: dict[str, dict[str, Any]] = {}
    for step in entry.get("steps", []):
        for row in step.get("results", []):
            out[result_key(str(step.get("name")), str(row["quantity"]))] = {
                k: row[k] for k in ("value", "stderr", "lo", "hi", "unit")}
    return out


def find_runs(root: str | os.PathLike[str], warn: Any = None, **filters: Any
              ) -> list[dict[str, Any]]:
    """The catalog entries of the runs under ``root`` that match ``filters`` (a ConfigError
    for a root that is not a folder or a bad filter)."""
    base = Path(root)
    if not base.is_dir():
        raise ConfigError("ROOT", str(root), "a folder of run folders (e.g. runs)")
    return select_entries(catalog_entries(base, warn), **filters)


def runs(root: str | os.PathLike[str] = "runs", **filters: Any) -> pd.DataFrame:
    """The runs under ``root`` as a pandas DataFrame, oldest first: one row per run with
    ``path``, ``name``, ``sample``, ``operator``, ``protocol``, ``rig``, ``status`` (a run
    killed mid-way is ``interrupted``), ``started`` and ``finished`` (wall time), ``clock``,
    ``tags``, ``note``, ``reason``, then each step result and fitted value as a column
    ``<step>/<quantity>`` (``ramp and hold/1-term G_e``, SI units) with ``... lo`` and
    ``... hi`` (95 % interval) where it has a standard error. ``filters``: ``sample``,
    ``operator``, ``protocol``, ``status`` (values or lists, ``*`` wildcards), ``tag``,
    ``since``, ``until`` (``"2026-11-25"``, ``"7d"``), as ``gelrig runs`` takes them. The
    index (``ROOT/.gelrig-runs.sqlite``) is brought up to date first."""
    import pandas as pd

    rows = []
    for entry in find_runs(root, **filters):
        row: dict[str, Any] = {key: entry.get(key) for key in COLUMNS}
        for key, result in flat_results(entry).items():
            row[key] = result["value"]
            if result["lo"] is not None:
                row[f"{key} lo"], row[f"{key} hi"] = result["lo"], result["hi"]
        rows.append(row)
    frame = pd.DataFrame(rows, columns=None if rows else list(COLUMNS))
    for key in ("started", "finished"):
        frame[key] = pd.to_datetime(frame[key].replace("", None), format="%Y-%m-%dT%H:%M:%S%z",
                                    errors="coerce", utc=True)
    return frame


@dataclass
class LoadedStep:
    """One recorded step: its ``columns`` (numpy arrays, SI, read on first use) and their
    ``units``, its ``results`` and ``params`` as run.json holds them. ``step["force_N"]``
    is ``step.columns["force_N"]``."""

    index: int
    name: str
    kind: str
    status: str
    path: Path
    results: dict[str, Any] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)
    _columns: dict[str, FloatArray] | None = field(default=None, repr=False)
    _units: dict[str, str] | None = field(default=None, repr=False)

    @property
    def columns(self) -> dict[str, FloatArray]:
        """Column name -> samples (a file a crash left open is read all the same)."""
        if self._columns is None:
            from gelrig.instrument.core.store import read_step

            self._columns = read_step(self.path)
        return self._columns

    @property
    def units(self) -> dict[str, str]:
        """Column name -> unit (``t_s``: ``s``, ``force_N``: ``N``)."""
        if self._units is None:
            from gelrig.instrument.core.store import open_step

            with open_step(self.path) as data:
                self._units = {name: str(ds.attrs.get("unit", ""))
                               for name, ds in data.datasets.items()}
        return self._units

    def __getitem__(self, column: str) -> FloatArray:
        return self.columns[column]

    def frame(self) -> pd.DataFrame:
        """The columns as a DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.columns)

    def __repr__(self) -> str:
        return f"LoadedStep({self.index}: {self.name!r}, {self.kind}, {self.status})"


@dataclass
class LoadedRun:
    """A run read back: ``steps`` by name (recorded order; a repeated name gets ``#index``),
    ``meta`` (run.json), and the catalog's ``summary`` (sample, operator, note, tags,
    protocol, status) and ``results`` (``<step>/<quantity>`` -> value, stderr, lo, hi,
    unit)."""

    path: Path
    meta: dict[str, Any]
    summary: dict[str, Any]
    steps: dict[str, LoadedStep]
    results: dict[str, dict[str, Any]]

    @property
    def sample(self) -> str:
        return str(self.summary.get("sample", ""))

    @property
    def status(self) -> str:
        return str(self.summary.get("status", ""))

    def __iter__(self) -> Iterator[LoadedStep]:
        return iter(self.steps.values())

    def __repr__(self) -> str:
        return (f"LoadedRun({self.path.name}: sample {self.sample!r}, "
                f"{self.summary.get('protocol')!r}, {self.status}, "
                f"steps {list(self.steps)})")


def load_run(path: str | os.PathLike[str]) -> LoadedRun:
    """A run folder read back: its steps (``.steps[name].columns`` numpy arrays with
    ``.units``, read on first use), its metadata, and its results with intervals. A run
    killed mid-way reads as far as it was flushed (its status ``interrupted``)."""
    from gelrig.instrument.core.catalog import live_status
    from gelrig.instrument.core.store import RunDirectory

    run = RunDirectory(os.fspath(path))
    meta = run.read_metadata()
    summary = summarise_run(meta)
    summary["status"], _ = live_status(run.path, summary["status"])
    steps: dict[str, LoadedStep] = {}
    for record in meta["steps"]:
        name = str(record["name"])
        key = name if name not in steps else f"{name} #{record['index']}"
        steps[key] = LoadedStep(int(record["index"]), name, str(record["kind"]),
                                str(record["status"]), run.step_file(record),
                                dict(record.get("results") or {}),
                                dict(record.get("params") or {}))
    return LoadedRun(run.path, meta, summary, steps, flat_results(summary))
