"""Text at the edges of the GUI: lab times, quantities with units, typed entries -> TOML values."""

from __future__ import annotations

import math

#: SI prefixes used for display (values stay SI inside).
_PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "µ"),
             (1e-9, "n"))


def quantity(value: float, unit: str, digits: int = 4) -> str:
    """``0.0062, 'm'`` -> '6.2 mm'; units that a prefix would garble ('1/s', '') stay plain."""
    if not math.isfinite(value):
        return f"{value} {unit}".strip()
    if not unit or unit[0].isdigit() or unit in ("rad", "Hz", "s"):
        return f"{value:.{digits}g} {unit}".strip()
    mag = abs(value)
    if mag == 0:
        return f"0 {unit}"
    for scale, prefix in _PREFIXES:
        if mag >= scale * 0.9999:
            return f"{value / scale:.{digits}g} {prefix}{unit}"
    return f"{value:.{digits}g} {unit}"


def entry_value(text: str) -> int | float | str:
    """A typed entry as a protocol-file value: a number if it reads as one, else the string
    (which may carry units, '0.3 mm/s'); validation then is exactly the protocol file's."""
    text = text.strip()
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def entry_text(value: object) -> str:
    """A protocol-file value as the text of an entry (the inverse of :func:`entry_value`)."""
    if isinstance(value, list):
        return ", ".join(entry_text(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)
