"""Fault injection for tests: the line noise, silences and firmware gaps a driver must survive."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field


@dataclass
class FaultPlan:
    """Faults the simulator applies to its next replies; thread-safe.

    ``mangle`` replies lose their closing bracket (a framing error on the host); ``silent``
    replies are dropped after the command has run (a timeout on the host); commands named in
    ``unknown`` are answered as unknown, as a firmware that lacks them would (code 10).
    """

    mangle: int = 0
    silent: int = 0
    unknown: set[str] = field(default_factory=set)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def mangle_next(self, count: int = 1) -> None:
        with self._lock:
            self.mangle += count

    def silence_next(self, count: int = 1) -> None:
        with self._lock:
            self.silent += count

    def reject(self, *names: str) -> None:
        """Answer the table commands ``names`` with 'unknown command'."""
        with self._lock:
            self.unknown.update(names)

    def clear(self) -> None:
        with self._lock:
            self.mangle = self.silent = 0
            self.unknown.clear()

    def apply(self, lines: list[str]) -> list[str]:
        """The reply lines as they leave the instrument."""
        with self._lock:
            if self.silent > 0:
                self.silent -= 1
                return []
            if self.mangle > 0 and lines:
                self.mangle -= 1
                return [lines[0][:-1], *lines[1:]]
        return lines

    def rejects(self, name: str) -> bool:
        with self._lock:
            return name in self.unknown
