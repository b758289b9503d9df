"""Serve a simulated KDC101 + Z825B on its APT wire protocol over TCP or a pty.

``gelrig sim serve kdc101 --tcp 127.0.0.1:5025 --clock paced:10`` then any APT client connects
to ``socket://127.0.0.1:5025`` (pyserial URL); with ``--pty`` it connects to the printed
``/dev/pts/N``. Time runs real or paced (k x real); a virtual clock needs an in-process client.
"""

from __future__ import annotations

import abc
import argparse
import contextlib
import logging
import math
import os
import select
import signal
import socket
import sys
import threading
import tty
from types import FrameType

from gelrig.instrument.core.clock import Clock, clock_from_spec
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.options import config_from_options
from gelrig.simulators.kdc101.config import SimConfig
from gelrig.simulators.kdc101.device import KDC101Simulator
from gelrig.simulators.serve_options import kdc101_arguments as add_arguments

POLL_S = 0.002  # how often the loop looks for due status updates and motion events

log = logging.getLogger("gelrig.simulators.kdc101")


class _Server(abc.ABC):
    """One client at a time; bytes in go to the simulator, its output goes back out."""

    def __init__(self, sim: KDC101Simulator):
        self.sim = sim
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    address = ""

    @abc.abstractmethod
    def serve_forever(self) -> None:
        """Serve clients until ``stop``."""

    def start(self) -> _Server:
        """Serve on a daemon thread (tests, benchmarks); ``stop`` ends it."""
        self._thread = threading.Thread(target=self.serve_forever, daemon=True,
                                        name=f"kdc101-sim {self.address}")
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self.close()

    @abc.abstractmethod
    def close(self) -> None:
        """Release sockets / file descriptors."""

    def _wait(self) -> float:
        """Real seconds to wait for the host's bytes: at most POLL_S, and no later than the
        simulator's next message on a paced clock (a status update goes out at its period in
        lab time, not POLL_S times the pace later)."""
        clock = self.sim.clock
        rate = float(getattr(clock, "rate", 1.0))
        if not math.isfinite(rate):
            return POLL_S
        due = (self.sim.next_event_time() - clock.now()) / rate
        return min(POLL_S, max(0.0, due)) if math.isfinite(due) else POLL_S

    def _pump(self, fd: int, recv: int, send: int) -> bool:
        """One turn: read what came, answer what is due. False when the peer is gone (or
        the simulator failed: logged, and the link is dropped, never the server)."""
        readable, _, _ = select.select([recv], [], [], self._wait())
        if readable:
            try:
                data = os.read(recv, 4096)
            except OSError:
                return False
            if not data:
                return False
            try:
                self.sim.receive(data)
            except Exception:  # the simulator drops what it cannot take; this is a bug
                log.exception("kdc101 simulator at %s: receiving %d bytes failed; dropped",
                              self.address, len(data))
        if not self.sim.connected:
            return False
        try:
            out = self.sim.read()
        except Exception:
            log.exception("kdc101 simulator at %s: producing output failed; dropping the link",
                          self.address)
            return False
        if out:
            try:
                _write_all(send, out)
            except OSError:
                return False
        return True


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        try:
            n = os.write(fd, view)
        except BlockingIOError:
            return  # the peer is not reading (a pty with no client): the bytes are lost
        view = view[n:]


class TcpServer(_Server):
    """APT over a TCP socket (clients use the pyserial URL ``socket://host:port``)."""

    def __init__(self, sim: KDC101Simulator, host: str = "127.0.0.1", port: int = 0):
        super().__init__(sim)
        self._listener = socket.create_server((host, port))
        self._listener.settimeout(0.1)
        h, p = self._listener.getsockname()[:2]
        self.address = f"socket://{h}:{p}"
        self.refused = 0  # second clients turned away while one was connected

    def serve_forever(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with conn:
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.sim.reconnect()
                self.sim.discard_output()
                fd = conn.fileno()
                while not self._stop.is_set() and self._pump(fd, fd, fd):
                    self._refuse_others()

    def _refuse_others(self) -> None:
        """A second client is closed at once, as a serial port in use refuses a second open."""
        readable, _, _ = select.select([self._listener], [], [], 0)
        if not readable:
            return
        try:
            extra, peer = self._listener.accept()
        except OSError:
            return
        self.refused += 1
        log.warning("kdc101 simulator at %s: refused a second client %s (one at a time, "
                    "like a serial port)", self.address, peer)
        extra.close()

    def close(self) -> None:
        self._listener.close()


class PtyServer(_Server):
    """APT over a pseudo-terminal (clients open the printed ``/dev/pts/N``)."""

    def __init__(self, sim: KDC101Simulator):
        super().__init__(sim)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # binary frames: no echo, no line discipline
        os.set_blocking(self._master, False)  # nobody listening: drop, don't block
        self.address = os.ttyname(self._slave)

    def serve_forever(self) -> None:
        while not self._stop.is_set():
            # We hold the slave end open, so a client closing it is not an error here.
            self._pump(self._master, self._master, self._master)

    def close(self) -> None:
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


def _config(args: argparse.Namespace) -> SimConfig:
    return config_from_options(SimConfig, args, "gelrig sim serve kdc101")


def _clock(spec: str) -> Clock:
    if spec.strip().lower() == "virtual":
        raise ConfigError("--clock", spec, "a served simulator runs real or paced:K (virtual "
                          "time needs an in-process client: kdc101sim://NAME)")
    return clock_from_spec(spec, waits_only=False)


def _parse_tcp(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ConfigError("--tcp", text, "expected HOST:PORT, e.g. 127.0.0.1:5025")
    return host or "127.0.0.1", int(port)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted (or ``--duration``); prints where it listens."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    sim = KDC101Simulator(_clock(args.clock), _config(args))
    server: _Server = TcpServer(sim, *_parse_tcp(args.tcp)) if args.tcp else PtyServer(sim)
    print(f"kdc101 simulator (serial {sim.config.serial_number}, clock {args.clock}) "
          f"listening on {server.address}", flush=True)

    def _terminate(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
    server.start()
    try:
        assert server._thread is not None
        server._thread.join(timeout=args.duration)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gelrig.simulators.kdc101.serve",
                                     description=__doc__)
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
