"""Validated tables of SI parameters, for rig files, protocol files and forms.

A :class:`Field` names a key, its SI unit, its allowed range and its default; ``parse_table``
turns a TOML table (numbers in SI, or strings with units such as "0.3 mm/s") into SI floats,
raising one ConfigError that names the file, the field, the value and the allowed range.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from instrument.errors import ConfigError
from instrument.units import to_si


@dataclass(frozen=True)
class Field:
    """One parameter: ``unit`` is an SI unit string ('' for a pure number)."""

    key: str
    unit: str
    default: float | None = None
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    integer: bool = False
    help: str = ""

    def allowed(self) -> str:
        lo = "(" if self.lo_open else "["
        unit = f" {self.unit}" if self.unit else ""
        kind = "an integer" if self.integer else "a number"
        return f"allowed: {kind} in {lo}{self.lo:g}, {self.hi:g}]{unit}"

    def parse(self, raw: object, prefix: str = "", source: str | None = None) -> float:
        name = f"{prefix}{self.key}"
        if isinstance(raw, bool) or not isinstance(raw, str | int | float):
            raise ConfigError(name, raw, f"expected a number; {self.allowed()}", source)
        value = to_si(raw, self.unit or "dimensionless", name, source)
        return self.check(value, prefix, source)

    def check(self, value: float, prefix: str = "", source: str | None = None) -> float:
        name = f"{prefix}{self.key}"
        low_ok = value > self.lo if self.lo_open else value >= self.lo
        if not (math.isfinite(value) and low_ok and value <= self.hi):
            raise ConfigError(name, value, self.allowed(), source)
        if self.integer and value != int(value):
            raise ConfigError(name, value, self.allowed(), source)
        return value


def parse_table(
    table: Mapping[str, Any],
    fields: Sequence[Field],
    prefix: str = "",
    source: str | None = None,
    ignore: Sequence[str] = (),
) -> dict[str, float]:
    """SI values for every field: given ones parsed and checked, missing ones defaulted.

    Unknown keys (other than ``ignore``) and missing fields without a default are errors.
    """
    by_key = {f.key: f for f in fields}
    for key, raw in table.items():
        if key not in by_key and key not in ignore:
            allowed = ", ".join(sorted(by_key))
            raise ConfigError(f"{prefix}{key}", raw, f"unknown field; allowed: {allowed}", source)
    out: dict[str, float] = {}
    for f in fields:
        if f.key in table:
            out[f.key] = f.parse(table[f.key], prefix, source)
        elif f.default is None:
            raise ConfigError(f"{prefix}{f.key}", "missing", f"required; {f.allowed()}", source)
        else:
            out[f.key] = f.default
    return out


def read_toml(path: str | Path, what: str) -> dict[str, Any]:
    """A TOML file as a table; ConfigError naming the file if unreadable or malformed."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(what, str(path), f"cannot be read ({exc.strerror})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("TOML", str(path), f"not valid TOML: {exc}") from None
