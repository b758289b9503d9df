"""Interlocks checked on every sample: the first sample beyond a limit trips."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from gelrig.instrument.physics.contact import FloatArray


@dataclass(frozen=True)
class Interlock:
    """Trips when ``|column|`` (or the signed value, if not ``absolute``) exceeds ``limit``."""

    name: str
    column: str
    limit: float
    unit: str
    absolute: bool = True

    def first_violation(self, data: Mapping[str, FloatArray]) -> int | None:
        """Index of the first sample beyond the limit in a block, or None."""
        values = data.get(self.column)
        if values is None or len(values) == 0:
            return None
        v = np.abs(values) if self.absolute else np.asarray(values)
        beyond = v > self._limit
        first = int(beyond.argmax())  # the first True, or 0 when there is none
        return first if beyond[first] else None

    @cached_property
    def _limit(self) -> np.ndarray:
        """The limit as a 0-d array: a comparison with it is the same, and faster (blocks are
        small and come thousands of times) than with a Python float."""
        return np.array(float(self.limit))

    def headroom(self, value: float) -> float:
        """Distance of a value from the limit (negative when beyond)."""
        return self.limit - (abs(value) if self.absolute else value)


@dataclass(frozen=True)
class Trip:
    """What tripped, on which sample (index within its block) and with what value."""

    interlock: Interlock
    index: int
    value: float
    t: float

    @property
    def message(self) -> str:
        """'interlock force: 50.3 mN beyond the limit 50 mN at t = 12.345 s' (lab units:
        lengths in mm, forces in mN, torques in mN*m)."""
        il = self.interlock
        return (f"interlock {il.name}: {lab(self.value, il.unit)} beyond the limit "
                f"{lab(il.limit, il.unit, '.6g')} at t = {self.t:.3f} s")


#: SI unit -> (lab unit, factor) of the messages people read.
LAB_UNITS = {"m": ("mm", 1e3), "N": ("mN", 1e3), "N*m": ("mN*m", 1e3)}


def lab(value: float, unit: str, spec: str = ".4g") -> str:
    """An SI value in the lab's unit: ``0.00250091, "m"`` -> '2.501 mm'."""
    shown, factor = LAB_UNITS.get(unit, (unit, 1.0))
    return f"{value * factor:{spec}} {shown}"


def check(interlocks: tuple[Interlock, ...], data: Mapping[str, FloatArray]) -> Trip | None:
    """The earliest trip in a block across all interlocks, or None."""
    earliest: Trip | None = None
    t = data.get("t_s")
    for il in interlocks:
        i = il.first_violation(data)
        if i is not None and (earliest is None or i < earliest.index):
            value = float(data[il.column][i])
            earliest = Trip(il, i, value, float(t[i]) if t is not None else float("nan"))
    return earliest
