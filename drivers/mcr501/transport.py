"""Line transport of the MCR 501 over pyvisa, mapping VISA failures to typed errors.

Any VISA resource string works: ``ASRL/dev/ttyUSB0::INSTR`` or ``ASRL1::INSTR`` for the
instrument's RS-232 port (opened at 38400 baud, 8N1, XON/XOFF), or
``TCPIP0::127.0.0.1::PORT::SOCKET`` for the simulator.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from typing import Any, Protocol

from gelrig.drivers.mcr501.commands import BAUD_RATE, DATA_BITS, TERMINATION
from gelrig.instrument.core.errors import (
    Disconnected,
    FramingError,
    InstrumentTimeout,
    NotSent,
)

_TERM_BYTES = TERMINATION.encode("ascii")


class LineTransport(Protocol):
    """What the driver needs from a transport: lines out, lines in."""

    def write_line(self, line: str) -> None:
        """Send one line (termination added by the transport)."""
        ...

    def read_line(self) -> str:
        """Receive one line without its termination; raise InstrumentTimeout if none comes."""
        ...

    def read_lines(self, n: int, min_length: int = 1,
                   rest: Callable[[bytes], int] | None = None) -> list[str]:
        """Receive ``n`` lines (a stream reply's records): the same lines as ``read_line``
        ``n`` times, in as few transport calls as the caller's bounds allow. Each line holds
        at least ``min_length`` characters before its termination; ``rest(begun)`` is the
        fewest bytes (termination included) that can complete a line begun with ``begun``."""
        ...

    def discard_input(self) -> None:
        """Drop whatever has arrived but not been read (resynchronise after a fault)."""
        ...

    def reply_timeout(self, seconds: float) -> AbstractContextManager[None]:
        """Within the block, a read waits at most ``seconds`` (never longer than usual)."""
        ...

    def close(self) -> None:
        """Release the transport."""
        ...


def open_resource_manager(backend: str = "@py") -> Any:
    """A pyvisa ResourceManager for ``backend`` (``"@py"``: pyvisa-py; ``""``: the default)."""
    import pyvisa

    return pyvisa.ResourceManager(backend) if backend else pyvisa.ResourceManager()


class VisaTransport:
    """A pyvisa message-based resource carrying the bracketed ASCII dialect.

    ``timeout`` is the reply timeout in real seconds (VISA timeouts are wall-clock).
    ``resource_manager`` is shared if given (and then not closed here).
    """

    def __init__(
        self,
        resource: str,
        timeout: float = 2.0,
        backend: str = "@py",
        resource_manager: Any = None,
        baud_rate: int = BAUD_RATE,
    ):
        import pyvisa
        from pyvisa import constants

        self._own_rm = resource_manager is None
        self._rm = open_resource_manager(backend) if resource_manager is None else resource_manager
        self.resource_name = resource
        self._timeout_ms = max(1, round(timeout * 1000))
        try:
            self._res = self._rm.open_resource(
                resource,
                read_termination=TERMINATION,
                write_termination=TERMINATION,
                timeout=self._timeout_ms,
                encoding="ascii",
            )
            if resource.upper().startswith("ASRL"):
                self._res.baud_rate = baud_rate
                self._res.data_bits = DATA_BITS
                self._res.parity = constants.Parity.none
                self._res.stop_bits = constants.StopBits.one
                self._res.flow_control = constants.ControlFlow.xon_xoff
        except (pyvisa.errors.VisaIOError, OSError, ValueError) as exc:
            if self._own_rm:
                self._rm.close()
            raise Disconnected(f"MCR 501: cannot open {resource!r}: {exc}") from exc
        self._closed = False

    @property
    def resource(self) -> Any:
        """The underlying pyvisa resource (for inspection in tests)."""
        return self._res

    def _map(self, exc: Exception, doing: str) -> Exception:
        import pyvisa
        from pyvisa import constants

        if isinstance(exc, pyvisa.errors.VisaIOError):
            if exc.error_code == constants.StatusCode.error_timeout:
                return InstrumentTimeout(
                    f"MCR 501 on {self.resource_name}: no reply within "
                    f"{self._res.timeout / 1000:g} s while {doing}"
                )
            return Disconnected(f"MCR 501 on {self.resource_name}: {doing} failed: {exc}")
        if isinstance(exc, UnicodeError):
            return FramingError(f"MCR 501 on {self.resource_name}: non-ASCII bytes while {doing}")
        return Disconnected(f"MCR 501 on {self.resource_name}: {doing} failed: {exc}")

    def _peer_closed(self) -> bool:
        """True if the resource is a socket whose peer has closed (pyvisa-py only).

        pyvisa-py reports a closed TCP peer as a read timeout; peeking at its socket tells
        the two apart so that a pulled cable reads as Disconnected.
        """
        try:
            sock = self._rm.visalib.sessions[self._res.session].interface
        except Exception:
            return False
        if not isinstance(sock, socket.socket):
            return False
        try:
            return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except BlockingIOError:
            return False
        except OSError:
            return True

    def write_line(self, line: str) -> None:
        if self._closed:
            raise NotSent(f"MCR 501 on {self.resource_name}: transport closed")
        try:
            self._res.write(line)
        except Exception as exc:
            mapped = self._map(exc, f"sending {line!r}")
            if isinstance(mapped, Disconnected):  # the write failed: nothing left
                raise NotSent(str(mapped)) from exc
            raise mapped from exc

    def read_line(self) -> str:
        if self._closed:
            raise Disconnected(f"MCR 501 on {self.resource_name}: transport closed")
        try:
            return str(self._res.read())
        except Exception as exc:
            raise self._read_failed(exc) from exc

    def _read_failed(self, exc: Exception) -> Exception:
        mapped = self._map(exc, "waiting for a reply")
        if isinstance(mapped, InstrumentTimeout) and self._peer_closed():
            mapped = Disconnected(f"MCR 501 on {self.resource_name}: connection closed")
        return mapped

    def read_lines(self, n: int, min_length: int = 1,
                   rest: Callable[[bytes], int] | None = None) -> list[str]:
        """``n`` lines read as bytes with the termination character off (docs/decisions/0393).

        Each read asks for the fewest bytes the unfinished lines can still hold (the rest of
        a begun line by ``rest``, then ``min_length`` and the termination per line), so it
        never reads past the ``n`` lines (never waits for bytes that are not coming); a reply
        of records comes in a few reads instead of one per line. Split at the terminations
        here: the same lines, the same bytes on the wire.
        """
        if n <= 0:
            return []
        if self._closed:
            raise Disconnected(f"MCR 501 on {self.resource_name}: transport closed")
        from pyvisa import constants

        line = max(1, min_length) + len(_TERM_BYTES)
        buf = bytearray()
        done, tail = 0, 0  # complete lines in buf; bytes after the last termination
        res = self._res
        try:
            res.set_visa_attribute(constants.ResourceAttribute.termchar_enabled, False)
            try:
                while done < n:
                    if tail:
                        begun = bytes(buf[len(buf) - tail:])
                        first = max(1 if begun.endswith(_TERM_BYTES[:1]) else 2, line - tail,
                                    1 if rest is None else rest(begun))
                    else:
                        first = line
                    need = first + (n - done - 1) * line
                    start = max(0, len(buf) - 1)  # a termination may straddle two reads
                    buf += res.read_bytes(need)
                    done += buf.count(_TERM_BYTES, start)
                    tail = len(buf) - (buf.rfind(_TERM_BYTES) + len(_TERM_BYTES)) if done \
                        else len(buf)
            finally:
                res.set_visa_attribute(constants.ResourceAttribute.termchar_enabled, True)
            lines = buf.decode("ascii").split(TERMINATION)
        except Exception as exc:
            raise self._read_failed(exc) from exc
        lines.pop()  # after the last termination
        return lines

    @contextlib.contextmanager
    def reply_timeout(self, seconds: float) -> Iterator[None]:
        ms = max(1, min(self._timeout_ms, round(seconds * 1000)))
        if self._closed or ms == self._timeout_ms:
            yield
            return
        self._res.timeout = ms
        try:
            yield
        finally:
            with contextlib.suppress(Exception):
                self._res.timeout = self._timeout_ms

    def discard_input(self) -> None:
        if self._closed:
            return
        before = self._res.timeout  # the usual one, or a shorter reply_timeout in force
        self._res.timeout = 20
        # Read until the short timeout says the input is empty (the failure is the goal).
        with contextlib.suppress(Exception):
            for _ in range(10_000):
                self._res.read_raw()
        self._res.timeout = before

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(Exception):
            self._res.close()
        if self._own_rm:
            with contextlib.suppress(Exception):
                self._rm.close()
