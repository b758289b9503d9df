"""A loopback TCP proxy between a driver and a simulator server that injects wire faults.

The driver connects to :attr:`FaultProxy.port` instead of the server's; bytes are relayed both
ways until a fault is set for the server-to-driver direction (the replies):

- ``garbage()``: each reply chunk is replaced by as many bytes of noise;
- ``truncate()``: the next reply chunk is cut to its first half, later ones vanish;
- ``swallow()``: replies vanish (the instrument looks silent, the connection stays up);
- ``delay(s)``: each reply chunk is held back ``s`` seconds;
- ``close()``: every connection is closed now, and new ones are refused (accepted and closed);
- ``drop()``: every connection is closed now; new ones are relayed (a cable pulled and
  plugged back, the instrument up all along);
- ``heal()``: back to relaying.

Bounded by construction: it listens on 127.0.0.1 only, every wait has a timeout, and it stops
by itself after ``lifetime`` seconds even if a test forgets to stop it.
"""

from __future__ import annotations

import contextlib
import queue
import random
import select
import socket
import threading
import time
from collections.abc import Callable
from types import TracebackType

_POLL_S = 0.05


class FaultProxy:
    """Relay ``127.0.0.1:<port>`` to ``upstream`` with injectable faults on the replies."""

    def __init__(self, upstream_port: int, upstream_host: str = "127.0.0.1", *,
                 lifetime: float = 120.0, seed: int = 12):
        self._upstream = (upstream_host, upstream_port)
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(8)
        self._listener.settimeout(_POLL_S)
        self.port: int = self._listener.getsockname()[1]
        self._end = time.monotonic() + lifetime
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._mode = "relay"
        self._delay_s = 0.0
        self._refuse = False
        self._pairs: list[tuple[socket.socket, socket.socket]] = []
        self._threads: list[threading.Thread] = []
        self._random = random.Random(seed)
        self.replies_seen = 0  # reply chunks that reached the proxy (relayed or not)
        self.requests = bytearray()  # every byte relayed to the server, in order
        self.replies = bytearray()  # every byte delivered to the driver, in order
        self._spawn(self._accept_loop)

    # ---- faults --------------------------------------------------------------------------
    def _set(self, mode: str, delay_s: float = 0.0) -> None:
        with self._lock:
            self._mode, self._delay_s = mode, delay_s

    def heal(self) -> None:
        """Relay faithfully again (and accept new connections)."""
        self._refuse = False
        self._set("relay")

    def garbage(self) -> None:
        self._set("garbage")

    def truncate(self) -> None:
        self._set("truncate")

    def swallow(self) -> None:
        self._set("swallow")

    def delay(self, seconds: float) -> None:
        self._set("delay", seconds)

    def close(self) -> None:
        """Drop every open connection now and refuse new ones until :meth:`heal`."""
        self._refuse = True
        self.drop()

    def drop(self) -> None:
        """Drop every open connection now; new ones are accepted and relayed."""
        with self._lock:
            pairs, self._pairs = self._pairs, []
        for a, b in pairs:
            _close(a)
            _close(b)

    # ---- lifecycle -----------------------------------------------------------------------
    @property
    def url(self) -> str:
        return f"127.0.0.1:{self.port}"

    def stop(self) -> None:
        """Stop relaying, close everything, and join the threads (bounded)."""
        self._stop.set()
        self.close()
        _close(self._listener)
        for t in self._threads:
            t.join(timeout=2.0)

    def __enter__(self) -> FaultProxy:
        return self

    def __exit__(self, *exc: tuple[type[BaseException] | None, BaseException | None,
                                   TracebackType | None]) -> None:
        self.stop()

    def _running(self) -> bool:
        return not self._stop.is_set() and time.monotonic() < self._end

    def _spawn(self, target: Callable[..., object], *args: object) -> None:
        t = threading.Thread(target=target, args=args, daemon=True)
        t.start()
        self._threads.append(t)

    # ---- relaying ------------------------------------------------------------------------
    def _accept_loop(self) -> None:
        while self._running():
            try:
                client, _ = self._listener.accept()
            except (TimeoutError, OSError):
                continue
            if self._refuse:
                _close(client)
                continue
            try:
                server = socket.create_connection(self._upstream, timeout=2.0)
            except OSError:
                _close(client)
                continue
            with self._lock:
                self._pairs.append((client, server))
            outbox: queue.Queue[tuple[float, bytes]] = queue.Queue()
            self._spawn(self._pump, client, server, None)
            self._spawn(self._pump, server, client, outbox)
            self._spawn(self._deliver, outbox, client)
        self._stop.set()
        self.close()

    def _pump(self, src: socket.socket, dst: socket.socket,
              replies: queue.Queue[tuple[float, bytes]] | None) -> None:
        """Relay ``src`` to ``dst``; replies go through ``_fault`` and the delivery queue."""
        while self._running():
            try:
                ready, _, _ = select.select([src], [], [], _POLL_S)
                if not ready:
                    continue
                data = src.recv(65536)
            except (OSError, ValueError):
                break
            if not data:
                break
            if replies is not None:
                self.replies_seen += 1
                due, data = self._fault(data)
                replies.put((due, data))
                continue
            try:
                if data:
                    dst.sendall(data)
                    self.requests += data
            except OSError:
                break
        _close(src)
        _close(dst)

    def _deliver(self, outbox: queue.Queue[tuple[float, bytes]], dst: socket.socket) -> None:
        """Send each reply when due (a delay is latency: it does not add up over chunks)."""
        while self._running():
            try:
                due, data = outbox.get(timeout=_POLL_S)
            except queue.Empty:
                continue
            while self._running() and time.monotonic() < due:
                self._stop.wait(min(_POLL_S, due - time.monotonic()))
            try:
                if data:
                    dst.sendall(data)
                    self.replies += data
            except OSError:
                break

    def _fault(self, data: bytes) -> tuple[float, bytes]:
        """When to deliver a reply chunk, and what to deliver of it."""
        now = time.monotonic()
        with self._lock:
            mode, delay_s = self._mode, self._delay_s
            if mode == "truncate":
                self._mode = "swallow"  # the rest of that reply never comes
        if mode == "garbage":
            return now, bytes(self._random.getrandbits(8) for _ in data)
        if mode == "truncate":
            return now, data[: max(1, len(data) // 2)]
        if mode == "swallow":
            return now, b""
        return now + (delay_s if mode == "delay" else 0.0), data


def _close(sock: socket.socket) -> None:
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_RDWR)
    sock.close()


def failing(call: Callable[[], object], error: type[Exception] | tuple[type[Exception], ...]
            ) -> tuple[Exception, float]:
    """The error ``call()`` raised (it must raise ``error``) and the seconds it took."""
    import pytest

    t0 = time.monotonic()
    with pytest.raises(error) as info:
        call()
    return info.value, time.monotonic() - t0
