"""The confirmed rig file: the user's rig file with bring-up's confirmed values written in.

Everything the user wrote stays as written (comments, order, the ``[simulator]`` table), but
for each confirmed value's line, which becomes::

    # was: counts_per_mm = 34554.96  -- ADR 0003
    counts_per_mm = 34304.2  # confirmed: 2026-11-28 | operator: ana | method: ... | u: ...

The old line is kept as a ``# was:`` comment (its comment's UNVERIFIED mark removed); the
provenance (date, operator, method, uncertainty) sits beside the new value as one
``# confirmed:`` comment with ``|``-separated fields. A key the file did not have is added at
the end of its table (the table is added if missing). The result is read back with the rig
file reader before it is written, so a confirmed file is always a valid rig file.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.rigfile import RigSpec, parse_rig

_HEADER = re.compile(r"^\s*\[\s*([A-Za-z0-9_.\-]+)\s*\]\s*(#.*)?$")


@dataclass(frozen=True)
class Confirmed:
    """One value bring-up confirmed: where it goes, what it is, and how it was found."""

    table: str  # "stage", "force.chain"
    key: str
    value: float | str  # as TOML will hold it: a number, or a string with its unit
    method: str
    uncertainty: str
    operator: str
    date: str  # ISO date and time, UTC

    @property
    def name(self) -> str:
        return f"[{self.table}] {self.key}"

    def toml_value(self) -> str:
        if isinstance(self.value, str):
            return '"' + self.value.replace("\\", "\\\\").replace('"', '\\"') + '"'
        return repr(float(self.value)) if not float(self.value).is_integer() \
            else f"{float(self.value):.1f}"

    def provenance(self) -> str:
        return (f"# confirmed: {self.date} | operator: {self.operator} | method: "
                f"{self.method} | u: {self.uncertainty}")


def _split_comment(line: str) -> tuple[str, str]:
    """``key = value  # comment`` -> (``key = value``, ``comment``), quotes respected."""
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            return line[:i].rstrip(), line[i + 1:].strip()
    return line.rstrip(), ""


def _unverified_removed(comment: str) -> str:
    text = re.sub(r"\bUNVERIFIED\b\s*[:;,]?", " ", comment, flags=re.IGNORECASE)
    text = re.sub(r"\(\s*\)", " ", text)
    return re.sub(r"\s{2,}", " ", text).strip(" ;,")


def _tables(lines: Sequence[str]) -> dict[str, tuple[int, int]]:
    """Table name -> (first line after its header, end line) of each ``[table]``."""
    spans: dict[str, tuple[int, int]] = {}
    name, start = "", 0
    for i, line in enumerate(lines):
        match = _HEADER.match(line)
        if match:
            spans.setdefault(name, (start, i))
            name, start = match.group(1), i + 1
    spans.setdefault(name, (start, len(lines)))
    return spans


def _key_line(lines: Sequence[str], span: tuple[int, int], key: str) -> int | None:
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for i in range(*span):
        if pattern.match(lines[i]):
            return i
    return None


def apply(text: str, values: Sequence[Confirmed], source: str = "<rig>") -> str:
    """``text`` (a rig file) with ``values`` written in; ConfigError if a value's line is not a
    one-line ``key = value`` or the result is not a valid rig file."""
    lines = text.splitlines()
    for item in values:
        spans = _tables(lines)
        new = f"{item.key} = {item.toml_value()}  {item.provenance()}"
        if item.table not in spans:
            lines += ["", f"[{item.table}]", new]
            continue
        span = spans[item.table]
        at = _key_line(lines, span, item.key)
        if at is None:
            end = span[1]
            while end > span[0] and not lines[end - 1].strip():
                end -= 1
            lines.insert(end, new)
            continue
        body, comment = _split_comment(lines[at])
        try:
            tomllib.loads(body)
        except tomllib.TOMLDecodeError:
            raise ConfigError(item.name, body.split("=", 1)[-1].strip(),
                              "a one-line value to replace (bring-up writes only those)",
                              source) from None
        old = body.strip()
        note = _unverified_removed(comment) if comment else ""
        indent = lines[at][: len(lines[at]) - len(lines[at].lstrip())]
        lines[at:at + 1] = [f"{indent}# was: {old}" + (f"  -- {note}" if note else ""),
                            indent + new]
    out = "\n".join(lines) + "\n"
    check(out, source)
    return out


def check(text: str, source: str) -> RigSpec:
    """Read ``text`` back as a rig file (what ``gelrig`` will do with it)."""
    try:
        root = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("confirmed rig file", source, f"not valid TOML ({exc})") from None
    return parse_rig(root, source)


def write(rig_file: Path, out: Path, values: Sequence[Confirmed]) -> Path:
    """Write ``rig_file`` with ``values`` confirmed to ``out`` (``rig_file`` is not touched)."""
    text = apply(rig_file.read_text(encoding="utf-8"), values, str(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(out)
    return out


__all__ = ["Confirmed", "apply", "check", "write"]
