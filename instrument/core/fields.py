"""Typed configuration: fields that carry their unit, default, range and help, read from TOML.

Every configuration of gelrig (stage, force input, load-cell chain, rheometer, rig limits,
simulator truth, step parameters) is a :class:`Config` dataclass whose fields are declared
with :func:`param` and a spec (:class:`Field` for a number with a unit, :class:`FieldList`
for a list of them, :class:`Choice` for one of a few words, :class:`Text` for a free string,
:class:`Flag` for a switch).
One reader, :meth:`Config.from_table`, builds any of them from a TOML table and reports
every error in one format::

    rig.toml: [stage] max_velocity = "9 mm/s": allowed (0, 2.6] mm/s

The value is shown as the user wrote it and the allowed range in the unit they wrote it in
(SI when they wrote a bare number). Values inside are SI floats.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol, Self

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.units import convert, to_si

#: Deepest nesting of tables and arrays a configuration file may have.
MAX_DEPTH = 16
_NUMBER_THEN_UNIT = re.compile(r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*(.+?)\s*$")


@dataclass(frozen=True)
class Where:
    """Where a value came from: a file (``source``) and a table (``section``: "stage",
    "force.chain", "step[2]"); names a key as ``[section] key``."""

    section: str = ""
    source: str | None = None

    def name(self, key: str) -> str:
        return f"[{self.section}] {key}" if self.section else key

    def error(self, key: str, value: object, allowed: str) -> ConfigError:
        return ConfigError(self.name(key), value, allowed, self.source)

    def sub(self, section: str) -> Where:
        """A nested table: ``[stage]`` -> ``[stage.sub]``."""
        return Where(f"{self.section}.{section}" if self.section else section, self.source)


def _fmt(x: float) -> str:
    return "inf" if math.isinf(x) else f"{x:.6g}"


def written_unit(raw: object) -> str | None:
    """The unit of a string such as ``"9 mm/s"`` as written (``"mm/s"``), else None."""
    if not isinstance(raw, str):
        return None
    m = _NUMBER_THEN_UNIT.match(raw)
    return m.group(1) if m else None


class Spec(Protocol):
    """What every field spec provides to the reader."""

    @property
    def key(self) -> str: ...

    @property
    def help(self) -> str: ...

    @property
    def required(self) -> bool: ...

    def parse(self, raw: object, where: Where) -> Any: ...

    def check(self, value: Any, where: Where) -> Any: ...

    def allowed(self, unit: str | None = None) -> str: ...

    def initial(self) -> Any: ...


REQUIRED: Any = object()
"""Default of a field that must be given."""


@dataclass(frozen=True)
class Field:
    """A number: ``unit`` is its SI unit ('' for a pure number; 'rpm' for the rheometer's
    arm speeds, the one unit people and the instrument both count in); ``lo``/``hi`` bound it.

    ``default`` None (or :data:`REQUIRED`) makes the field required unless ``optional``, in
    which case a missing value is None. ``display`` is the unit people read it in (plans,
    forms), e.g. "mm" for a field held in m.
    """

    key: str
    unit: str
    default: float | None = None
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    integer: bool = False
    help: str = ""
    optional: bool = False
    display: str = ""

    @property
    def required(self) -> bool:
        return self.default is None and not self.optional

    def initial(self) -> float | None:
        return None if self.default is REQUIRED else self.default

    def allowed(self, unit: str | None = None) -> str:
        """``allowed (0, 2.6] mm/s`` in ``unit`` (default: the SI unit)."""
        lo, hi, shown = self.lo, self.hi, self.unit
        if unit and unit != self.unit:
            try:
                lo, hi = (b if math.isinf(b) else convert(b, self.unit or "dimensionless", unit)
                          for b in (self.lo, self.hi))
                shown = unit
            except ConfigError:
                pass
        bracket = "(" if self.lo_open else "["
        kind = "an integer in " if self.integer else ""
        text = f"allowed {kind}{bracket}{_fmt(lo)}, {_fmt(hi)}]"
        return f"{text} {shown}" if shown else text

    def parse(self, raw: object, where: Where) -> float:
        """SI value of ``raw`` (a number in SI, or a string with a unit), range-checked."""
        if raw is None and self.optional:
            return None  # type: ignore[return-value]
        if isinstance(raw, bool) or not isinstance(raw, str | int | float):
            raise where.error(self.key, raw, f"expected a number; {self.allowed()}")
        value = to_si(raw, self.unit or "dimensionless", where.name(self.key), where.source)
        return self._check(value, raw, where)

    def check(self, value: Any, where: Where) -> float | None:
        """Range-check an SI value (None passes an optional field)."""
        if value is None and self.optional:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise where.error(self.key, value, f"expected a number; {self.allowed()}")
        return self._check(float(value), value, where)

    def _check(self, value: float, raw: object, where: Where) -> float:
        low_ok = value > self.lo if self.lo_open else value >= self.lo
        ok = math.isfinite(value) and low_ok and value <= self.hi
        if not ok or (self.integer and value != int(value)):
            raise where.error(self.key, raw, self.allowed(written_unit(raw)))
        return value


class _Optional:
    """Required exactly when there is no default."""

    default: Any

    @property
    def required(self) -> bool:
        return self.default is None

    def initial(self) -> Any:
        return self.default


@dataclass(frozen=True)
class Choice(_Optional):
    """One of a few words (case-folded by ``normalize`` if given)."""

    key: str
    choices: tuple[str, ...]
    default: str | None = None
    help: str = ""
    normalize: Callable[[str], str] | None = None

    def allowed(self, unit: str | None = None) -> str:
        return f"allowed: {', '.join(self.choices)}"

    def parse(self, raw: object, where: Where) -> str:
        if isinstance(raw, str) and self.normalize is not None:
            raw = self.normalize(raw)
        return self.check(raw, where)

    def check(self, value: Any, where: Where) -> str:
        if not isinstance(value, str) or value not in self.choices:
            raise where.error(self.key, value, self.allowed())
        return value


@dataclass(frozen=True)
class Text(_Optional):
    """A string that ``valid`` accepts; ``describe`` says what is allowed."""

    key: str
    default: str | None = None
    describe: str = "a string"
    valid: Callable[[str], bool] = bool
    help: str = ""

    def allowed(self, unit: str | None = None) -> str:
        return f"allowed: {self.describe}"

    def parse(self, raw: object, where: Where) -> str:
        return self.check(raw, where)

    def check(self, value: Any, where: Where) -> str:
        if not isinstance(value, str) or not self.valid(value):
            raise where.error(self.key, value, self.allowed())
        return value


@dataclass(frozen=True)
class Flag(_Optional):
    """A switch: a TOML boolean (the words ``true`` and ``false`` are taken too)."""

    key: str
    default: bool | None = None
    help: str = ""

    def allowed(self, unit: str | None = None) -> str:
        return "allowed: true or false"

    def parse(self, raw: object, where: Where) -> bool:
        if isinstance(raw, str) and raw in ("true", "false"):
            raw = raw == "true"
        return self.check(raw, where)

    def check(self, value: Any, where: Where) -> bool:
        if not isinstance(value, bool):
            raise where.error(self.key, value, self.allowed())
        return value


@dataclass(frozen=True)
class FieldList(_Optional):
    """A non-empty list of numbers, each within ``item``'s range (e.g. a ladder's speeds)."""

    key: str
    item: Field
    default: tuple[float, ...] | None = None
    help: str = ""
    #: most items allowed (None: no bound); checked before any item is read
    max_items: int | None = None

    def allowed(self, unit: str | None = None) -> str:
        most = f" of at most {self.max_items}" if self.max_items is not None else ""
        return f"a non-empty list{most}, each {self.item.allowed(unit)}"

    def _items(self, raw: object, where: Where, parse: bool) -> tuple[float, ...]:
        if not isinstance(raw, list | tuple) or not raw:
            unit = f" ({self.item.unit})" if self.item.unit else ""
            raise where.error(self.key, raw, f"a non-empty list of numbers{unit}")
        if self.max_items is not None and len(raw) > self.max_items:
            raise where.error(self.key, f"{len(raw):,} values",
                              f"at most {self.max_items} values")
        out = []
        for i, v in enumerate(raw):
            item = dataclasses.replace(self.item, key=f"{self.key}[{i}]")
            value = item.parse(v, where) if parse else item.check(v, where)
            out.append(float(value))  # type: ignore[arg-type]
        return tuple(out)

    def parse(self, raw: object, where: Where) -> tuple[float, ...]:
        return self._items(raw, where, parse=True)

    def check(self, value: Any, where: Where) -> tuple[float, ...]:
        return self._items(value, where, parse=False)


def param(spec: Spec) -> Any:
    """A dataclass field declared by its spec (its default is the spec's default)."""
    default = spec.initial()
    if spec.required:
        return dataclasses.field(metadata={"spec": spec})
    return dataclasses.field(default=default, metadata={"spec": spec})


class Config:
    """Base of every validated configuration dataclass.

    Subclasses are ``@dataclass(frozen=True)`` with fields declared by :func:`param`; they
    set ``section`` (the table they are read from) and may override :meth:`validate` for
    checks across fields. Constructing one checks every field, so a config built in code
    obeys the same ranges as one read from a file.
    """

    section: ClassVar[str] = ""
    #: Store the values of integer fields as ``int`` (else as read: a float, as SI values are).
    exact_integers: ClassVar[bool] = False

    def __post_init__(self) -> None:
        where = Where(self.section)
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            spec = f.metadata.get("spec")
            if spec is not None:
                value = spec.check(getattr(self, f.name), where)
                if self.exact_integers and getattr(spec, "integer", False) and value is not None:
                    object.__setattr__(self, f.name, int(value))
        self.validate(where)

    def validate(self, where: Where) -> None:
        """Checks across fields; raise ``where.error(key, value, allowed)``."""

    @classmethod
    def specs(cls) -> dict[str, Spec]:
        """Attribute name -> spec, in declaration order."""
        return {f.name: f.metadata["spec"] for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                if "spec" in f.metadata}

    @classmethod
    def from_table(
        cls,
        table: Mapping[str, Any],
        source: str | None = None,
        section: str | None = None,
        ignore: Sequence[str] = (),
    ) -> Self:
        """Build from a TOML table: given values parsed and checked, missing ones defaulted.

        Unknown keys (other than ``ignore``) and missing required fields are errors.
        """
        where = Where(cls.section if section is None else section, source)
        values = read_table(table, cls.specs(), where, ignore)
        try:
            return cls(**values)
        except ConfigError as exc:  # a check across fields, made without the file's name
            field = exc.field
            own = f"[{cls.section}] "
            if where.section != cls.section and field.startswith(own):
                field = where.name(field.removeprefix(own))
            raise ConfigError(field, exc.value, exc.allowed, exc.source or source) from None

    def to_table(self) -> dict[str, Any]:
        """Values by TOML key (SI numbers), for storing beside the data."""
        return {spec.key: getattr(self, name) for name, spec in self.specs().items()}


def read_table(
    table: Mapping[str, Any],
    specs: Mapping[str, Spec],
    where: Where,
    ignore: Sequence[str] = (),
) -> dict[str, Any]:
    """Attribute name -> parsed value for every spec; the one reader behind every config."""
    if not isinstance(table, Mapping):
        raise ConfigError(f"[{where.section}]" if where.section else "table", table,
                          "a table is required here", where.source)
    by_key = {spec.key: (name, spec) for name, spec in specs.items()}
    for key, raw in table.items():
        if key not in by_key and key not in ignore:
            raise where.error(key, raw, f"unknown field; allowed: {', '.join(sorted(by_key))}")
    out: dict[str, Any] = {}
    for key, (name, spec) in by_key.items():
        if key in table:
            out[name] = spec.parse(table[key], where)
        elif spec.required:
            raise where.error(key, "missing", f"required; {spec.allowed()}")
        else:
            out[name] = spec.initial()
    return out


def _depth(value: object, level: int = 0) -> int:
    if level > MAX_DEPTH:
        return level
    if isinstance(value, dict):
        return max((_depth(v, level + 1) for v in value.values()), default=level)
    if isinstance(value, list):
        return max((_depth(v, level + 1) for v in value), default=level)
    return level


def read_toml(path: str | Path, what: str) -> dict[str, Any]:
    """A TOML file as a table; ConfigError naming the file if unreadable or malformed."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError(what, str(path), f"cannot be read ({exc.strerror})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(what, str(path), f"not UTF-8 text (byte {exc.start}); save the file "
                          "as UTF-8") from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("TOML", str(path), f"not valid TOML: {exc}") from None
    except RecursionError:
        raise ConfigError("TOML", str(path), f"nested deeper than {MAX_DEPTH} levels") from None
    if _depth(table) > MAX_DEPTH:
        raise ConfigError("TOML", str(path), f"nested deeper than {MAX_DEPTH} levels")
    return table
