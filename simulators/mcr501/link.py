"""A socket-free line transport straight into a simulator, for fast in-process work.

It meets the driver's LineTransport contract structurally (no import of the driver), so a
protocol test or a benchmark can run the real driver code without a TCP round trip.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from gelrig.instrument.core.errors import Disconnected, InstrumentTimeout
from gelrig.simulators.mcr501.instrument import MCR501Simulator


class DirectLink:
    """Lines go to :meth:`MCR501Simulator.handle`; replies queue until read."""

    def __init__(self, simulator: MCR501Simulator):
        self.simulator = simulator
        self._pending: deque[str] = deque()
        self._closed = False

    def write_line(self, line: str) -> None:
        if self._closed:
            raise Disconnected("MCR 501 direct link closed")
        self._pending.extend(self.simulator.handle(line))

    def read_line(self) -> str:
        if self._closed:
            raise Disconnected("MCR 501 direct link closed")
        if not self._pending:
            raise InstrumentTimeout("MCR 501 direct link: no reply pending")
        return self._pending.popleft()

    def read_lines(self, n: int, min_length: int = 1,
                   rest: Callable[[bytes], int] | None = None) -> list[str]:
        """``n`` lines, as ``read_line`` n times (all that is pending at once when it is n)."""
        pending = self._pending
        if len(pending) == n and not self._closed:
            lines = list(pending)
            pending.clear()
            return lines
        return [self.read_line() for _ in range(n)]

    def discard_input(self) -> None:
        self._pending.clear()

    @contextmanager
    def reply_timeout(self, seconds: float) -> Iterator[None]:
        """Replies are there at once or never: nothing to shorten."""
        yield

    def close(self) -> None:
        self._closed = True
