"""A configuration's fields as command-line options, from the same declarations.

``--key-with-dashes`` per field of a :class:`~gelrig.instrument.core.fields.Config`: its help
and default come from the field's spec (so ``--help`` shows the defaults the rig file
documents), values are read by the spec's own parser (a number in SI or with a unit,
``"0.1 mm"``; one of the choices; a switch), and an error names the option::

    gelrig sim serve kdc101: --travel = "3 N": expected a length in m

Light to import (argparse only): ``gelrig --help`` builds these options without loading any
simulator. Options left out keep the field's default.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Collection, Mapping
from typing import Any, TypeVar

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import Choice, Config, Field, Flag, Spec, Text, Where

C = TypeVar("C", bound=Config)

#: SI prefixes a display unit may carry over its SI unit ("mm" over "m", "um/N" over "m/N").
_PREFIXES = {"G": 1e9, "M": 1e6, "k": 1e3, "m": 1e-3, "u": 1e-6, "n": 1e-9}


def option(spec: Spec) -> str:
    """The option of a field: ``--`` and its key with dashes (``--home-offset``)."""
    return "--" + spec.key.replace("_", "-")


def _number(value: float) -> str:
    return f"{value:.10g}"


def shown_default(spec: Spec) -> str:
    """A spec's default as a person reads it: ``25 mm``, ``34554.96``, ``true``, ``cutoff``."""
    default = spec.initial()
    if isinstance(spec, Flag):
        return "true" if default else "false"
    if not isinstance(spec, Field) or default is None:
        return str(default)
    unit, value = spec.unit, float(default)
    display = spec.display
    if display and display != unit and display[0] in _PREFIXES and display[1:] == unit:
        unit, value = display, value / _PREFIXES[display[0]]
    return f"{_number(value)} {unit}" if unit else _number(value)


def _with(spec: Spec, **changes: Any) -> Any:
    """A copy of a (frozen dataclass) spec with ``changes``."""
    return dataclasses.replace(spec, **changes)  # type: ignore[type-var]


def add_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup,
                cls: type[Config], only: Collection[str] | None = None,
                defaults: Mapping[str, Any] | None = None) -> None:
    """Add an option per field of ``cls`` (or per attribute named in ``only``). ``defaults``
    (attribute -> value) replaces a field's default where the caller's differs: what it
    shows and what :func:`config_from_options` fills in."""
    for name, spec in cls.specs().items():
        if only is not None and name not in only:
            continue
        if defaults and name in defaults:
            spec = _with(spec, default=defaults[name])
        text = spec.help or name.replace("_", " ")
        if spec.initial() is not None:
            text = f"{text} (default {shown_default(spec)})"
        common: dict[str, Any] = {"dest": spec.key, "default": None,
                                  "help": text.replace("%", "%%")}
        if isinstance(spec, Flag):
            parser.add_argument(option(spec), action=argparse.BooleanOptionalAction, **common)
        elif isinstance(spec, Choice):
            parser.add_argument(option(spec), choices=spec.choices, **common)
        elif isinstance(spec, Field):
            metavar = "N" if spec.integer else ("VALUE" if spec.unit else "NUMBER")
            parser.add_argument(option(spec), metavar=metavar, **common)
        elif isinstance(spec, Text):
            parser.add_argument(option(spec), metavar="TEXT", **common)


def config_from_options(cls: type[C], args: argparse.Namespace, source: str,
                        only: Collection[str] | None = None,
                        defaults: Mapping[str, Any] | None = None) -> C:
    """``cls`` built from the options :func:`add_options` added: given ones parsed and checked
    (ConfigError naming the option and ``source``), the rest at their defaults (``defaults``
    first, as given to :func:`add_options`)."""
    where = Where("", source)
    values: dict[str, Any] = dict(defaults or {})
    specs = cls.specs()
    for name, spec in specs.items():
        if only is not None and name not in only:
            continue
        raw = getattr(args, spec.key, None)
        if raw is None:
            continue
        values[name] = _with(spec, key=option(spec)).parse(raw, where)
    try:
        return cls(**values)
    except ConfigError as exc:  # a check across fields: name the option
        field = exc.field
        for spec in specs.values():
            if field in (spec.key, f"[{cls.section}] {spec.key}"):
                field = option(spec)
        raise ConfigError(field, exc.value, exc.allowed, exc.source or source) from None
