"""Where a campaign's results live: one Parquet part per finished member, then one table.

Each member's record is written as ``OUT/parts/<member_id>.parquet`` the moment it finishes
(a temporary file, fsync, rename: a part is whole or absent), so a campaign killed at any
point keeps every finished member and a rerun skips them. :meth:`ResultStore.consolidate`
gathers the parts of the campaign's members into ``OUT/results.parquet`` (one row per member,
no duplicates: a member id names one part).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from instrument.errors import ConfigError

RESULTS = "results.parquet"
PARTS = "parts"


class ResultStore:
    """The results folder of one campaign (``--out``)."""

    def __init__(self, out: str | Path):
        self.out = Path(out)
        self.parts = self.out / PARTS
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
        """Ids of the members whose record is stored (without failed ones if asked)."""
        ids = {p.stem for p in self.parts.glob("*.parquet")}
        if retry_failed and ids:
            ids -= {r["member_id"] for r in self.read(ids) if r.get("status") == "failed"}
        return ids

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
        """The stored records of ``ids`` (those that exist), in the order given."""
        rows = []
        for member_id in ids:
            path = self._part(member_id)
            if path.exists():
                rows.extend(pq.read_table(path).to_pylist())
        return rows

    def consolidate(self, ids: Iterable[str]) -> pa.Table:
        """Write ``results.parquet``: one row per stored member of ``ids``; returns it."""
        tables = [pq.read_table(self._part(i)) for i in dict.fromkeys(ids)
                  if self._part(i).exists()]
        table = (pa.concat_tables(tables, promote_options="permissive") if tables
                 else pa.table({"member_id": pa.array([], pa.string())}))
        self._create()
        path = self.out / RESULTS
        tmp = path.with_name(f".{path.name}.tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, path)
        return table
