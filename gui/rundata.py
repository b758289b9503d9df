"""The samples of a run as the GUI holds them: growing numpy buffers per step.

The runner's thread appends (through the event bridge); the GUI thread reads views at its own
pace (20-30 Hz), so a plot never waits for the run and the run never waits for a plot. Only
the columns the plots and readouts use are kept; the recorder keeps everything on disk.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gelrig.instrument.physics.contact import FloatArray

#: Columns kept for plotting and live readouts (compression and shear steps).
KEPT = ("t_s", "force_N", "position_m", "theta_m", "angle_rad", "torque_Nm",
        "normal_force_N", "gap_m", "pass", "direction", "speed_m_s", "overlap_m")
_START = 4096


class Columns:
    """Equal-length growing float64 columns with one writer and any number of readers.

    The writer fills rows past ``n`` (growing into new arrays when full: readers holding the
    old ones keep valid data), and only then moves ``n`` on, under the caller's lock; so a
    reader never waits for a copy, and a view stays valid while appends go on.
    """

    def __init__(self, names: tuple[str, ...]):
        self.names = names
        self._arrays = {name: np.empty(_START) for name in names}
        self.n = 0

    def write(self, data: Mapping[str, FloatArray]) -> int:
        """Write a block past the end (not yet visible); returns its length."""
        n_new = len(next(iter(data.values()))) if data else 0
        if n_new == 0 or not self.names:
            return 0
        need = self.n + n_new
        arrays = self._arrays
        capacity = next(iter(arrays.values())).size
        if need > capacity:
            capacity = max(need, capacity * 2)
            grown = {}
            for name, old in arrays.items():
                grown[name] = np.empty(capacity)
                grown[name][: self.n] = old[: self.n]
            self._arrays = arrays = grown  # one reference swap: readers see old or new
        for name, array in arrays.items():
            source = data.get(name)
            array[self.n: need] = np.nan if source is None else source
        return n_new

    def append(self, data: Mapping[str, FloatArray]) -> int:
        """Write a block and make it visible (for a single thread)."""
        n_new = self.write(data)
        self.n += n_new
        return n_new

    def views(self, start: int = 0) -> dict[str, FloatArray]:
        n = self.n
        return {name: array[start: n] for name, array in self._arrays.items()}

    def nbytes(self) -> int:
        return sum(a.nbytes for a in self._arrays.values())


@dataclass
class StepData:
    """One step: its identity, column units, kept columns, and how it ended."""

    index: int
    name: str
    kind: str
    units: dict[str, str]
    columns: Columns
    status: str = "running"
    results: dict[str, Any] = field(default_factory=dict)


class RunData:
    """Every step's kept columns, safe to append from one thread and read from another."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._steps: dict[int, StepData] = {}
        self.version = 0  # bumped on every change, so a redraw can skip when nothing is new
        #: the run's first sample time (s, run clock): plots show time from the run's start
        self.t0: float | None = None

    def begin_step(self, index: int, name: str, kind: str, units: Mapping[str, str]) -> None:
        names = tuple(c for c in KEPT if c in units)
        with self._lock:
            self._steps[index] = StepData(index, name, kind, dict(units), Columns(names))
            self.version += 1

    def append(self, index: int, data: Mapping[str, FloatArray]) -> None:
        """Add a block (from the one writer thread); the copy happens outside the lock."""
        with self._lock:
            step = self._steps.get(index)
            if step is None:  # samples without a StepStarted (a test double): keep them
                names = tuple(c for c in KEPT if c in data)
                step = StepData(index, f"step {index}", "", {}, Columns(names))
                self._steps[index] = step
        n_new = step.columns.write(data)
        if n_new:
            if self.t0 is None and "t_s" in data:
                self.t0 = float(data["t_s"][0])
            with self._lock:
                step.columns.n += n_new
                self.version += 1

    def finish_step(self, index: int, status: str, results: Mapping[str, Any]) -> None:
        with self._lock:
            step = self._steps.get(index)
            if step is not None:
                step.status = status
                step.results = dict(results)
                self.version += 1

    def steps(self) -> list[tuple[StepData, dict[str, FloatArray]]]:
        """Each step with views of its columns, in step order."""
        with self._lock:
            return [(s, s.columns.views()) for _, s in sorted(self._steps.items())]

    def samples(self) -> int:
        with self._lock:
            return sum(s.columns.n for s in self._steps.values())

    def nbytes(self) -> int:
        """Memory held by the kept columns (capacity included)."""
        with self._lock:
            return sum(s.columns.nbytes() for s in self._steps.values())

    def latest(self) -> dict[str, float]:
        """The newest value of every kept column (live readouts during a run)."""
        with self._lock:
            if not self._steps:
                return {}
            views = self._steps[max(self._steps)].columns.views()
        return {k: float(v[-1]) for k, v in views.items() if v.size}
