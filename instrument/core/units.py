"""Unit-bearing strings at the edges ("0.78 mm", "4 kPa", "2000 s") -> SI floats inside.

pint does the parsing and the dimension check; a bare number is taken as SI already.
"""

from __future__ import annotations

import math
import sys
from functools import lru_cache
from typing import Any

from gelrig.instrument.core.errors import ConfigError


def _import_pint() -> Any:
    """pint, without the dask that ``pint.compat`` imports when it is installed (~0.2 s of a
    start-up, for pint's dask-array support, which gelrig does not use) unless dask is
    already loaded (a campaign)."""
    if "pint" in sys.modules or "dask" in sys.modules:
        import pint

        return pint
    sys.modules["dask"] = None  # type: ignore[assignment]  # find_spec("dask") -> None
    try:
        import pint
    finally:
        if sys.modules.get("dask", 0) is None:
            del sys.modules["dask"]
    return pint


@lru_cache(maxsize=1)
def _registry() -> Any:
    """The one unit registry, its parsed definitions cached on disk by pint (~0.02 s instead
    of ~0.2 s at a start-up; the same definitions, so the same conversions)."""
    pint = _import_pint()
    try:
        return pint.UnitRegistry(cache_folder=":auto:")
    except Exception:  # no writable cache folder: parse the definitions
        return pint.UnitRegistry()


def to_si(value: str | float | int, unit: str, field: str, source: str | None = None) -> float:
    """Convert ``value`` to the SI ``unit`` ('m', 'Pa', 's', 'm/s', 'N', 'N*m', '1/s', 'Hz').

    Raises ConfigError naming ``field`` if the value is not a number of that dimension.
    """
    if isinstance(value, bool):
        raise ConfigError(field, value, f"expected a number in {unit}", source)
    if isinstance(value, int | float):
        out = float(value)
    else:
        text = str(value).strip()
        try:
            out = float(text)
        except ValueError:
            out = _parse_with_units(text, unit, field, source)
    if not math.isfinite(out):
        raise ConfigError(field, value, f"expected a finite number in {unit}", source)
    return out


def _parse_with_units(text: str, unit: str, field: str, source: str | None) -> float:
    ureg = _registry()
    pint = sys.modules["pint"]
    try:
        q = ureg.Quantity(text)
        return float(q.to(unit).magnitude)
    except pint.DimensionalityError:
        allowed = f"expected a quantity in {unit} (dimension mismatch)"
        raise ConfigError(field, text, allowed, source) from None
    except Exception:
        allowed = f"expected a number or a quantity like '1.5 {unit}'"
        raise ConfigError(field, text, allowed, source) from None


def convert(value: float, unit: str, to: str) -> float:
    """``value`` in ``unit`` expressed in ``to`` (ConfigError if the dimensions differ)."""
    if unit == to:
        return value
    try:
        return float(_registry().Quantity(value, unit).to(to).magnitude)
    except Exception:
        raise ConfigError("unit", to, f"not convertible from {unit}") from None


def positive(value: float, field: str, unit: str, source: str | None = None) -> float:
    """Return ``value`` if > 0, else raise ConfigError naming the field."""
    if not value > 0:
        raise ConfigError(field, value, f"must be > 0 {unit}".rstrip(), source)
    return value


def lab_time(seconds: float) -> str:
    """A duration for people: '1 h 02 min', '3 min 20 s', '12.5 s'; '?' when unknown."""
    if not math.isfinite(seconds):
        return "?"
    seconds = max(seconds, 0.0)
    if seconds >= 3600:
        return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"
    if seconds >= 60:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{seconds:.1f} s"
