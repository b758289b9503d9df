"""Where a campaign's results live: one Parquet part per finished member, then one table.

Each member's record is written as ``OUT/parts/<member_id>.parquet`` the moment it finishes
(a temporary file, fsync, rename: a part is whole or absent), so a campaign killed at any
point keeps every finished member and a rerun skips them. :meth:`ResultStore.consolidate`
gathers the parts of the campaign's members into ``OUT/results.parquet`` (one row per member,
no duplicates: a member id names one part).

A part that cannot be read whole (truncated, garbage, not a regular file, not that member's
one record) is moved aside to ``OUT/parts/damaged/`` and reported in one line; its member is
then not finished, so the campaign runs it again.
"""

from __future__ import annotations

import logging
import os
import stat
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.store import check_path

RESULTS = "results.parquet"
PARTS = "parts"
DAMAGED = "damaged"

log = logging.getLogger(__name__)


class ResultStore:
    """The results folder of one campaign (``--out``)."""

    def __init__(self, out: str | Path, warn: Callable[[str], object] | None = None):
        self.out = Path(out)
        #: told one line per damaged part set aside (default: the log)
        self.warn = warn or log.warning
        #: the lines of the parts set aside so far
        self.set_aside: list[str] = []
        self.parts = self.out / PARTS
        check_path(self.out)
        if self.out.exists() and not self.out.is_dir():
            raise ConfigError("--out", str(self.out), "is a file, not a folder; name a folder")

    def _create(self) -> None:
        """The folders, made when the first record is written."""
        try:
            self.parts.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError("--out", str(self.out), f"cannot be created ({exc.strerror})"
                              ) from None

    def _part(self, member_id: str) -> Path:
        return self.parts / f"{member_id}.parquet"

    def finished(self, retry_failed: bool = False) -> set[str]:
        """Ids of the members whose record is stored whole (without failed ones if asked);
        every part is read, and a damaged one set aside (its member is not finished)."""
        ids = set()
        for path in sorted(self.parts.glob("*.parquet")):
            table = self._load(path)
            if table is None:
                continue
            status = (table.column("status")[0].as_py() if "status" in table.column_names
                      else None)
            if not (retry_failed and status == "failed"):
                ids.add(path.stem)
        return ids

    def _load(self, path: Path) -> pa.Table | None:
        """A part's one-row table, or None once a damaged part is set aside."""
        try:
            info = os.lstat(path)
            if not stat.S_ISREG(info.st_mode):
                raise ValueError("not a regular file")
            table = pq.read_table(path)
            ids = (table.column("member_id").to_pylist() if "member_id" in table.column_names
                   else [])
            if ids != [path.stem]:
                raise ValueError(f"holds {table.num_rows} record(s), not member {path.stem}'s "
                                 "one")
            return table
        except FileNotFoundError:
            return None
        except (pa.ArrowException, OSError, ValueError) as exc:
            self._set_aside(path, exc)
            return None

    def _set_aside(self, path: Path, exc: BaseException) -> None:
        why = " ".join(str(exc).split())[:160] or type(exc).__name__
        folder = self.parts / DAMAGED
        target = folder / path.name
        k = 1
        while target.exists() or target.is_symlink():
            target = folder / f"{path.stem}.{k}{path.suffix}"
            k += 1
        try:
            folder.mkdir(exist_ok=True)
            os.replace(path, target)
            where = f"moved to {target}"
        except OSError as move:
            where = f"could not be moved aside ({move.strerror}); remove it"
        line = (f"{path}: damaged part, not read ({why}); {where}; member {path.stem} runs "
                "again")
        self.set_aside.append(line)
        self.warn(line)

    def write(self, record: Mapping[str, Any]) -> Path:
        """Store one member's record durably (whole or not at all)."""
        self._create()
        path = self._part(str(record["member_id"]))
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        pq.write_table(pa.Table.from_pylist([dict(record)]), tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, path)
        return path

    def read(self, ids: Iterable[str]) -> list[dict[str, Any]]:
        """The stored records of ``ids`` (those stored whole), in the order given."""
        rows = []
        for member_id in ids:
            table = self._load(self._part(member_id))
            if table is not None:
                rows.extend(table.to_pylist())
        return rows

    def consolidate(self, ids: Iterable[str]) -> pa.Table:
        """Write ``results.parquet``: one row per stored member of ``ids``; returns it."""
        loaded = (self._load(self._part(i)) for i in dict.fromkeys(ids))
        tables = [t for t in loaded if t is not None]
        table = (pa.concat_tables(tables, promote_options="permissive") if tables
                 else pa.table({"member_id": pa.array([], pa.string())}))
        self._create()
        path = self.out / RESULTS
        tmp = path.with_name(f".{path.name}.tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, path)
        return table
