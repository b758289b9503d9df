"""The simulated USB-6001's digital lines and PFI terminals, as the twin sees and drives them.

Thirteen static DIO lines (P0.0-7, P1.0-3, P2.0; User Guide) and two PFI inputs (PFI 0: the
counter's edge input and a start trigger; PFI 1: a start trigger). A line reads what a DO
task drives on it, else the level the twin puts on the pin (:meth:`DigitalLines.set_input`);
an undriven, unconnected line reads high (weak pull-up, as the USB-6008/6009 guide states for
its lines; UNVERIFIED for the 6001). Lines keep their driven state when the task that wrote them
ends; ``reset`` makes every line an input again.

A PFI terminal's signal is a list of level changes on the shared clock plus, optionally, a
square wave (frequency, start, duty) from an external source; edges on it start triggered
tasks and are counted by ctr0. A DO line can be wired to a PFI terminal in the twin
(:meth:`DigitalLines.wire`): each level change a DO write makes on the line is then an edge
on the terminal at the time of the write (a loopback wire on the screw terminals).
"""

from __future__ import annotations

import bisect
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

#: lines per port: port0 8, port1 4, port2 1
PORT_LINES = (8, 4, 1)
PFI_TERMINALS = ("PFI0", "PFI1")
#: highest edge rate the counter input takes (Hz): 5 MHz (USB-6001 spec sheet, UNVERIFIED)
MAX_COUNTER_FREQUENCY = 5e6


def line_index(port: int, line: int) -> int:
    """Global index (0..12) of ``port``/``line``."""
    return sum(PORT_LINES[:port]) + line


def line_name(index: int) -> str:
    """``port<p>/line<l>`` of a global line index."""
    for port, width in enumerate(PORT_LINES):
        if index < width:
            return f"port{port}/line{index}"
        index -= width
    raise IndexError(index)


N_LINES = sum(PORT_LINES)


def _count_grid(a: float, b: float, first: float, period: float, end: float) -> int:
    """How many of ``first + k period`` (k >= 0, before ``end``) lie in (a, b]."""
    b = min(b, math.nextafter(end, -math.inf))
    if b < first or b <= a:
        return 0
    hi = math.floor((b - first) / period + 1e-9)
    lo = math.floor((a - first) / period + 1e-9) if a >= first else -1
    return max(0, hi - lo)


@dataclass
class SquareWave:
    """An external square wave on a PFI pin: rising edges at ``start + k / frequency``."""

    frequency: float
    start: float
    duty: float = 0.5
    end: float = math.inf

    def edges(self, a: float, b: float, rising: bool) -> int:
        period = 1.0 / self.frequency
        first = self.start if rising else self.start + self.duty * period
        return _count_grid(a, b, first, period, self.end)

    def first_edge(self, after: float, rising: bool) -> float:
        period = 1.0 / self.frequency
        first = self.start if rising else self.start + self.duty * period
        if after < first:
            return first if first < self.end else math.inf
        k = math.floor((after - first) / period + 1e-9) + 1
        t = first + k * period
        return t if t < self.end else math.inf

    def level(self, t: float) -> bool | None:
        if t < self.start or t >= self.end:
            return None
        return ((t - self.start) * self.frequency) % 1.0 < self.duty


@dataclass
class PfiSignal:
    """The signal on one PFI terminal: level changes (time, level) and an optional wave."""

    initial: bool = True  # pulled up when nothing drives it (UNVERIFIED)
    changes: list[tuple[float, bool]] = field(default_factory=list)
    wave: SquareWave | None = None

    def level(self, t: float) -> bool:
        if self.wave is not None and (w := self.wave.level(t)) is not None:
            return w
        i = bisect.bisect_right([c[0] for c in self.changes], t)
        return self.changes[i - 1][1] if i else self.initial

    def edges(self, a: float, b: float, rising: bool) -> int:
        """Active edges in (a, b]."""
        n = self.wave.edges(a, b, rising) if self.wave is not None else 0
        previous = self.initial
        for t, level in self.changes:
            if level != previous and level == rising and a < t <= b:
                n += 1
            previous = level
        return n

    def first_edge(self, after: float, rising: bool) -> float:
        """Time of the first active edge at or after ``after`` (inf: none known yet)."""
        best = self.wave.first_edge(after - 1e-12, rising) if self.wave is not None else math.inf
        previous = self.initial
        for t, level in self.changes:
            if level != previous and level == rising and t >= after:
                best = min(best, t)
                break
            previous = level
        return best


class DigitalLines:
    """The 13 DIO lines and the PFI terminals of one simulated USB-6001."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self.inputs = [True] * N_LINES  # what the twin puts on each pin (pull-up: high)
        self.driven: dict[int, bool] = {}  # lines a DO task drives -> level
        self.pfi = {name: PfiSignal() for name in PFI_TERMINALS}
        self.wires: dict[int, str] = {}  # DO line -> PFI terminal it is wired to
        #: every level a DO write put on a line: (time, line index, level)
        self.history: list[tuple[float, int, bool]] = []
        #: called with (terminal, time) after an edge is added to a PFI terminal
        self.listeners: list[Callable[[str, float], None]] = []

    # --- what the twin does ----------------------------------------------------------------

    def set_input(self, line: str | int, level: bool) -> None:
        """Put ``level`` on a pin from outside (read by DI while no DO task drives it)."""
        with self._lock:
            self.inputs[self._index(line)] = bool(level)

    def level(self, line: str | int) -> bool:
        """The level on a line now: the driven one, else the input."""
        with self._lock:
            i = self._index(line)
            return self.driven.get(i, self.inputs[i])

    def wire(self, line: str | int, terminal: str) -> None:
        """Loop a DO line to a PFI terminal: its level changes become edges there."""
        terminal = _terminal(terminal)
        with self._lock:
            self.wires[self._index(line)] = terminal

    def pfi_level_changes(self, terminal: str, changes: list[tuple[float, bool]]) -> None:
        """Add level changes (time, level) on a PFI terminal (e.g. a trigger pulse)."""
        name = _terminal(terminal)
        with self._lock:
            signal = self.pfi[name]
            signal.changes = sorted(signal.changes + [(float(t), bool(v)) for t, v in changes])
        for t, _ in changes:
            self._notify(name, float(t))

    def pulse(self, terminal: str, at: float, width: float = 1e-6) -> None:
        """A positive pulse on a PFI terminal: rising at ``at``, falling ``width`` later (a
        line resting high is pulled low ``width`` before, so the rising edge is at ``at``)."""
        name = _terminal(terminal)
        changes = [(at - width, False)] if self.pfi[name].level(at - width / 2) else []
        self.pfi_level_changes(name, [*changes, (at, True), (at + width, False)])

    def square_wave(self, terminal: str, frequency: float, start: float, duty: float = 0.5,
                    end: float = math.inf) -> None:
        """Drive a PFI terminal with a square wave from ``start`` (until ``end``)."""
        if not 0 < frequency <= MAX_COUNTER_FREQUENCY or not 0 < duty < 1:
            raise ValueError(f"a square wave of {frequency} Hz, duty {duty} is outside what "
                             f"the PFI input takes (0 < f <= {MAX_COUNTER_FREQUENCY:g} Hz)")
        name = _terminal(terminal)
        with self._lock:
            self.pfi[name].wave = SquareWave(frequency, start, duty, end)
        self._notify(name, start)

    # --- what the tasks do -----------------------------------------------------------------

    def drive(self, indices: list[int], levels: list[bool], t: float) -> None:
        """A DO write at time ``t``: the lines now drive ``levels``."""
        edges: list[tuple[str, float, bool]] = []
        with self._lock:
            for i, v in zip(indices, levels, strict=True):
                before = self.driven.get(i, self.inputs[i])
                self.driven[i] = bool(v)
                self.history.append((t, i, bool(v)))
                if i in self.wires and before != bool(v):
                    edges.append((self.wires[i], t, bool(v)))
        for terminal, when, level in edges:
            self.pfi_level_changes(terminal, [(when, level)])

    def read(self, indices: list[int]) -> list[bool]:
        with self._lock:
            return [self.driven.get(i, self.inputs[i]) for i in indices]

    def release_all(self) -> None:
        """Reset Device: every line an input again."""
        with self._lock:
            self.driven.clear()

    def _notify(self, terminal: str, t: float) -> None:
        for listener in list(self.listeners):
            listener(terminal, t)

    @staticmethod
    def _index(line: str | int) -> int:
        if isinstance(line, int):
            if not 0 <= line < N_LINES:
                raise ValueError(f"no line {line} on a USB-6001 (0..{N_LINES - 1})")
            return line
        text = line.strip().lower().split("/", 1)[-1] if line.count("/") > 1 else line.lower()
        for i in range(N_LINES):
            if line_name(i) == text.strip("/"):
                return i
        raise ValueError(f"no line {line!r} on a USB-6001")


def _terminal(text: str) -> str:
    name = text.strip().split("/")[-1].upper().replace(" ", "")
    if name not in PFI_TERMINALS:
        raise ValueError(f"no terminal {text!r} on a USB-6001 (PFI0, PFI1)")
    return name
