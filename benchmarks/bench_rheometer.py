"""Benchmark of the MCR 501 driver and simulator.

Run: ``.venv/bin/python benchmarks/bench_rheometer.py [--repeats N] [--count N]``

Prints the median command round trips per second over TCP (the driver through pyvisa-py, and
a raw socket sending literal bytes) and in-process (the driver over a socket-free link, and the
simulator's handler alone), each with its ratio to a baseline measured in the same run (a raw
loopback socket echo of the same lines), and the wall time of one virtual-time pass at
2.38e-5 m/s with a 10 Hz measurement stream through pyvisa-py.
"""

from __future__ import annotations

import argparse
import socket
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gelrig.drivers.mcr501 import MCR501, open_resource_manager
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics.sliding import SlidingGeometry
from gelrig.simulators.mcr501 import (
    DirectLink,
    MCR501Simulator,
    SimConfig,
    SimulatorServer,
)

REQUEST = b":TORQ[?]\r\n"


def _echo_server() -> tuple[socket.socket, int]:
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)

    def serve() -> None:
        conn, _ = srv.accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with conn:
            buf = b""
            while True:
                data = conn.recv(4096)
                if not data:
                    return
                buf += data
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    conn.sendall(b":TORQ[0.000123]\r\n" if line else b"")

    threading.Thread(target=serve, daemon=True).start()
    return srv, int(srv.getsockname()[1])


class _LineSocket:
    def __init__(self, port: int):
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""

    def ask(self, data: bytes) -> bytes:
        self.sock.sendall(data)
        while b"\r\n" not in self.buf:
            self.buf += self.sock.recv(4096)
        line, self.buf = self.buf.split(b"\r\n", 1)
        return line


def _rate(fn: Callable[[], object], count: int, repeats: int) -> float:
    """Median calls per second over ``repeats`` runs of ``count`` calls."""
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(count):
            fn()
        rates.append(count / (time.perf_counter() - t0))
    return statistics.median(rates)


def _pass_wall_time(rm: object) -> tuple[float, float]:
    """Wall and virtual seconds of one pass at 2.38e-5 m/s with a 10 Hz stream."""
    clock = VirtualClock()
    cfg = SimConfig(start_referenced=True)
    sim = MCR501Simulator(clock, cfg)
    geo = SlidingGeometry(cfg.r1, cfg.r2, 0.78e-3)
    speed, margin = 2.38e-5, 1e-3
    travel = 2 * (geo.psi0 + margin)
    start = cfg.lower_angle - (geo.psi0 + margin) / cfg.arm
    sim.cell.spin = sim.cell.spin.halt(clock.now())
    with SimulatorServer(sim) as server:
        drv = MCR501(server.resource, clock, resource_manager=rm).open()
        try:
            # place the arm before contact, then lower to delta_max = 0.78 mm
            t0 = time.perf_counter()
            v0 = clock.now()
            drv.rotate(4e-3)
            clock.sleep((start - drv.angle()) * cfg.arm / 4e-3)
            drv.stop()
            drv.set_gap(cfg.touch_gap - 0.78e-3)
            drv.start_stream(0.1)
            drv.rotate(speed)
            points = 0
            end = clock.now() + travel / speed
            while clock.now() < end:
                clock.sleep(min(1.0, end - clock.now()))
                points += len(drv.read_stream())
            drv.stop()
            wall = time.perf_counter() - t0
            virtual = clock.now() - v0
        finally:
            drv.close()
    if points < 0.99 * travel / speed * 10:
        raise RuntimeError(f"pass recorded only {points} points")
    return wall, virtual


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--count", type=int, default=500, help="round trips per repeat")
    args = parser.parse_args(argv)
    n, k = args.count, args.repeats

    echo, port = _echo_server()
    client = _LineSocket(port)
    baseline = _rate(lambda: client.ask(REQUEST), n, k)
    client.sock.close()
    echo.close()

    rm = open_resource_manager("@py")
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig())
    rows: list[tuple[str, float]] = []
    with SimulatorServer(sim) as server:
        raw = _LineSocket(server.port)
        rows.append(("TCP, raw socket -> simulator", _rate(lambda: raw.ask(REQUEST), n, k)))
        raw.sock.close()
        drv = MCR501(server.resource, clock, resource_manager=rm).open()
        rows.append(("TCP, driver via pyvisa-py -> simulator", _rate(drv.torque, n, k)))
        drv.close()
    direct = MCR501(DirectLink(sim), clock).open()
    rows.append(("in-process, driver via DirectLink", _rate(direct.torque, n, k)))
    rows.append(("in-process, simulator handler only", _rate(lambda: sim.handle(":TORQ[?]"), n, k)))

    passes = [_pass_wall_time(rm) for _ in range(max(3, k))]
    rm.close()

    print(f"MCR 501 round trips (median of {k} x {n}, command :TORQ[?])")
    print(f"  {'baseline: raw loopback socket echo':42s} {baseline:10.0f} /s   ratio 1.00")
    for name, rate in rows:
        print(f"  {name:42s} {rate:10.0f} /s   ratio {rate / baseline:.2f}")
    wall = statistics.median(w for w, _ in passes)
    print(
        f"virtual-time pass at 2.38e-5 m/s, delta_max 0.78 mm, 10 Hz stream via pyvisa-py: "
        f"{wall:.3f} s wall (median of {len(passes)}; {passes[0][1]:.0f} s virtual)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
