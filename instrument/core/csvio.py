"""CSV in and out with named SI columns (``t_s``, ``delta_m``, ``force_N`` ...).

Reading checks the header and every value, so a bad file gets one line naming the file,
the column, the line and what is allowed, never a traceback.
"""

from __future__ import annotations

import csv
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from gelrig.instrument.core.arrays import FloatArray
from gelrig.instrument.core.errors import ConfigError


def write_columns(path: str | Path, columns: Mapping[str, Sequence[float] | FloatArray]) -> Path:
    """Write equal-length columns under a header; returns the path written."""
    path = Path(path)
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    np.savetxt(tmp, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
    tmp.replace(path)
    return path


#: Most bytes a CSV row of one value takes as written ("%.10g" and a comma or newline).
CSV_BYTES_PER_VALUE = 18


def write_chunks(path: str | Path, names: Sequence[str],
                 chunks: Iterable[Mapping[str, FloatArray]]) -> int:
    """Write a header, then each chunk's columns (equal lengths) as rows; returns the rows
    written. Memory is one chunk; the file appears whole or not at all (written beside it,
    then renamed; removed if anything fails)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    rows = 0
    try:
        with tmp.open("w") as handle:
            handle.write(",".join(names) + "\n")
            for chunk in chunks:
                data = np.column_stack([np.asarray(chunk[n], dtype=float) for n in names])
                np.savetxt(handle, data, delimiter=",", fmt="%.10g")
                rows += data.shape[0]
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return rows


def read_columns(
    path: str | Path, required: Sequence[str], optional: Sequence[str] = ()
) -> dict[str, FloatArray]:
    """Read the named columns of a CSV with a header line; other columns are ignored."""
    path = Path(path)
    source = str(path)
    try:
        handle = path.open(newline="")
    except OSError as exc:
        raise ConfigError("file", source, f"cannot be read ({exc.strerror})") from None
    with handle:
        reader = csv.reader(handle)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise ConfigError(
                "header", "", "the file is empty; expected a header line", source
            ) from None
        except (csv.Error, UnicodeDecodeError) as exc:
            raise ConfigError("header", "?", f"not a CSV text file ({exc})", source) from None
        missing = [name for name in required if name not in header]
        if missing:
            raise ConfigError(
                f"column {missing[0]!r}",
                "missing",
                f"required columns: {', '.join(required)}; the header has: {', '.join(header)}",
                source,
            )
        wanted = [n for n in (*required, *optional) if n in header]
        index = [header.index(n) for n in wanted]
        fast = _fast_read(path, index)
        if fast is not None:
            return {name: fast[:, i].copy() for i, name in enumerate(wanted)}
        values: list[list[float]] = [[] for _ in wanted]
        try:
            for line_no, row in enumerate(reader, start=2):
                if not row or all(not cell.strip() for cell in row):
                    continue
                for slot, (name, col) in enumerate(zip(wanted, index, strict=True)):
                    values[slot].append(_number(row, col, name, line_no, source))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise ConfigError("file", source, f"not a readable CSV text file ({exc})") from None
    if not values or not values[0]:
        raise ConfigError("rows", 0, "the file has a header but no data rows", source)
    return {name: np.asarray(v, dtype=float) for name, v in zip(wanted, values, strict=True)}


def _fast_read(path: Path, index: list[int]) -> FloatArray | None:
    """numpy's C parser for well-formed files; None sends the caller to the checking path."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "no data": the slow path says it
            data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=index, ndmin=2)
    except (ValueError, IndexError, UnicodeDecodeError):
        return None
    if data.shape[0] == 0 or not np.all(np.isfinite(data)):
        return None
    return np.asarray(data, dtype=float)


def _number(row: list[str], col: int, name: str, line_no: int, source: str) -> float:
    if col >= len(row):
        raise ConfigError(f"line {line_no}, column {name!r}", "", "missing value", source)
    cell = row[col].strip()
    try:
        value = float(cell)
    except ValueError:
        raise ConfigError(
            f"line {line_no}, column {name!r}", cell, "expected a number", source
        ) from None
    if not math.isfinite(value):
        where = f"line {line_no}, column {name!r}"
        raise ConfigError(where, cell, "expected a finite number", source)
    return value
