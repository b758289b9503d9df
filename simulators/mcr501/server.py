"""TCP server for the simulated MCR 501: CR LF terminated lines, one thread per connection.

Reach it with pyvisa as ``TCPIP0::127.0.0.1::PORT::SOCKET`` (read and write termination
CR LF) or with a plain socket. In tests it runs in a thread of the test process and shares the
test's VirtualClock with the driver.
"""

from __future__ import annotations

import contextlib
import socket
import socketserver
import threading
from typing import Any

from drivers.mcr501.codec import error_line
from drivers.mcr501.commands import TERMINATION
from simulators.mcr501.instrument import MCR501Simulator

#: Longest request line accepted (bytes); longer input is answered with an error and dropped.
MAX_LINE = 1024


class _Handler(socketserver.StreamRequestHandler):
    server: _Server

    def handle(self) -> None:
        self.server.track(self.connection)
        try:
            while True:
                raw = self.rfile.readline(MAX_LINE + 1)
                if not raw:
                    return
                if not raw.endswith(b"\n") and len(raw) > MAX_LINE:
                    self._send([error_line(11, "line too long")])
                    self.rfile.readline()  # drop the rest of that line
                    continue
                try:
                    line = raw.decode("ascii")
                except UnicodeDecodeError:
                    self._send([error_line(10, "non-ASCII bytes")])
                    continue
                if not line.strip():
                    continue
                self._send(self.server.simulator.handle(line))
        except OSError:
            return
        finally:
            self.server.untrack(self.connection)

    def _send(self, lines: list[str]) -> None:
        if lines:
            self.wfile.write("".join(f"{ln}{TERMINATION}" for ln in lines).encode("ascii"))
            self.wfile.flush()


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
    block_on_close = False

    def __init__(self, address: tuple[str, int], simulator: MCR501Simulator):
        self.simulator = simulator
        self._connections: set[socket.socket] = set()
        self._conn_lock = threading.Lock()
        super().__init__(address, _Handler)

    def track(self, conn: socket.socket) -> None:
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._conn_lock:
            self._connections.add(conn)

    def untrack(self, conn: socket.socket) -> None:
        with self._conn_lock:
            self._connections.discard(conn)

    def drop_all(self) -> int:
        with self._conn_lock:
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
