"""Request lines out of a byte stream, as the instrument's bounded input buffer sees them.

A line ends at CR, LF or CR LF (the empty line between CR and LF is skipped), so a client
written for any of the three conventions is answered (docs/decisions/0110). At most
``max_line`` bytes of an unterminated line are held: a longer line is reported once as
:data:`TOO_LONG` and the rest of it, up to its end, is dropped.
"""

from __future__ import annotations

import re
from typing import Final

#: Stands for a line that exceeded the bound and was dropped.
TOO_LONG: Final = None

_ENDS = re.compile(rb"[\r\n]")


class LineSplitter:
    """Feed received bytes; get back complete request lines (without their ends)."""

    def __init__(self, max_line: int):
        if max_line < 1:
            raise ValueError(f"max_line must be >= 1, got {max_line}")
        self.max_line = max_line
        self._buf = bytearray()
        self._discarding = False

    @property
    def pending(self) -> int:
        """Bytes of an unterminated line held now (never more than ``max_line``)."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[bytes | None]:
        """The lines ``data`` completes, in order; :data:`TOO_LONG` where one was dropped."""
        out: list[bytes | None] = []
        parts = _ENDS.split(data)
        last = len(parts) - 1
        for i, part in enumerate(parts):
            terminated = i < last
            if self._discarding:
                self._discarding = not terminated
                continue
            if len(self._buf) + len(part) > self.max_line:
                out.append(TOO_LONG)
                self._buf.clear()
                self._discarding = not terminated
                continue
            self._buf += part
            if terminated:
                if self._buf:
                    out.append(bytes(self._buf))
                self._buf.clear()
        return out
