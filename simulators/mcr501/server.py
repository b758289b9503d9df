"""TCP server for the simulated MCR 501: one client at a time, bounded lines, CR LF replies.

Reach it with pyvisa as ``TCPIP0::127.0.0.1::PORT::SOCKET`` (read termination CR LF; requests
may end in CR, LF or CR LF) or with a plain socket. Like the instrument's RS-232 port it serves
one client: a second connection gets one ``#ERR[20;...]`` line and is closed, and the first
keeps control. A request longer than :data:`MAX_LINE` bytes is answered with one
``#ERR[11;line too long ...]`` and dropped up to its end (docs/decisions/0110). In tests it
runs in a thread of the test process and shares the test's VirtualClock with the driver.
"""

from __future__ import annotations

import contextlib
import socket
import socketserver
import threading
import time
from typing import Any

from gelrig.drivers.mcr501.codec import error_line
from gelrig.drivers.mcr501.commands import BUSY, TERMINATION
from gelrig.simulators.mcr501.instrument import MCR501Simulator
from gelrig.simulators.mcr501.lines import TOO_LONG, LineSplitter

#: Longest request line accepted (bytes, without its end); ten times the longest table request.
MAX_LINE = 256
#: How long a new connection waits for the previous client to go (s): a client that closes and
#: at once reopens must not be refused because the server has not yet seen the close.
HANDOVER = 0.5
#: How long a refused client's late bytes are drained before its socket is closed (s), so that
#: the close does not reset the connection before the client has read the error line.
_LINGER = 0.5
_RECV = 4096


def replies_to(chunk: bytes, splitter: LineSplitter, simulator: MCR501Simulator) -> list[str]:
    """The reply lines to the request lines ``chunk`` completes (the server loop's work on
    each received chunk): a line too long, not ASCII or not a request gets its ``#ERR``."""
    replies: list[str] = []
    for raw in splitter.feed(chunk):
        if raw is TOO_LONG:
            replies.append(error_line(11, f"line too long, at most {MAX_LINE} bytes"))
            continue
        try:
            line = raw.decode("ascii")
        except UnicodeDecodeError:
            replies.append(error_line(10, "non-ASCII bytes"))
            continue
        if line.strip():
            replies.extend(simulator.handle(line))
    return replies


class _Handler(socketserver.BaseRequestHandler):
    server: _Server
    request: socket.socket

    def handle(self) -> None:
        conn = self.request
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if not self.server.claim(conn, HANDOVER):
            self._refuse()
            return
        try:
            self._serve()
        except OSError:
            return
        finally:
            self.server.release(conn)

    def _serve(self) -> None:
        splitter = LineSplitter(MAX_LINE)
        simulator = self.server.simulator
        while True:
            chunk = self.request.recv(_RECV)
            if not chunk:
                return
            self._send(replies_to(chunk, splitter, simulator))

    def _refuse(self) -> None:
        conn = self.request
        with contextlib.suppress(OSError):
            self._send([error_line(BUSY, "instrument busy, another client is connected")])
            conn.shutdown(socket.SHUT_WR)
            deadline = time.monotonic() + _LINGER
            while (left := deadline - time.monotonic()) > 0:
                conn.settimeout(left)
                if not conn.recv(_RECV):
                    break

    def _send(self, lines: list[str]) -> None:
        if lines:
            self.request.sendall("".join(f"{ln}{TERMINATION}" for ln in lines).encode("ascii"))


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
    block_on_close = False

    def __init__(self, address: tuple[str, int], simulator: MCR501Simulator):
        self.simulator = simulator
        self._owner: socket.socket | None = None
        self._connections: set[socket.socket] = set()
        self._cond = threading.Condition()
        super().__init__(address, _Handler)

    def claim(self, conn: socket.socket, wait: float) -> bool:
        """Make ``conn`` the one client if the instrument is free within ``wait`` s."""
        with self._cond:
            self._connections.add(conn)
            if not self._cond.wait_for(lambda: self._owner is None, timeout=wait):
                self._connections.discard(conn)
                return False
            self._owner = conn
            return True

    def release(self, conn: socket.socket) -> None:
        with self._cond:
            self._connections.discard(conn)
            if self._owner is conn:
                self._owner = None
                self._cond.notify_all()

    def drop_all(self) -> int:
        with self._cond:
            conns = list(self._connections)
        for conn in conns:
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                conn.close()
        return len(conns)


class SimulatorServer:
    """Serve ``simulator`` on ``host:port`` (port 0: any free port) from a background thread.

    Use as a context manager, or call :meth:`start` and :meth:`close`.
    """

    def __init__(self, simulator: MCR501Simulator, host: str = "127.0.0.1", port: int = 0):
        self.simulator = simulator
        self._server = _Server((host, port), simulator)
        self._thread: threading.Thread | None = None

    @property
    def host(self) -> str:
        return str(self._server.server_address[0])

    @property
    def port(self) -> int:
        return int(self._server.server_address[1])

    @property
    def resource(self) -> str:
        """The VISA resource string that reaches this server."""
        return f"TCPIP0::{self.host}::{self.port}::SOCKET"

    def start(self) -> SimulatorServer:
        if self._thread is None:
            self._thread = threading.Thread(
                target=self._server.serve_forever,
                kwargs={"poll_interval": 0.05},
                name=f"mcr501-sim:{self.port}",
                daemon=True,
            )
            self._thread.start()
        return self

    def disconnect_clients(self) -> int:
        """Drop every open connection (a cable pulled); return how many were open."""
        return self._server.drop_all()

    def close(self) -> None:
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=5)
            self._thread = None
        self._server.drop_all()
        self._server.server_close()

    def __enter__(self) -> SimulatorServer:
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()
