"""APT request/reply round trips per second: in-process URL, TCP server, and a raw loopback
echo baseline measured in the same run.

    .venv/bin/python benchmarks/bench_apt.py [--repeats 5] [--n 2000]

Each figure is the median of several repeats; the request is MOT_REQ_POSCOUNTER (6 bytes),
the reply MOT_GET_POSCOUNTER (12 bytes). The TCP server and the echo server run as separate
processes, so the client does not share a GIL with them.
"""

from __future__ import annotations

import argparse
import socket
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import serial

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gelrig.drivers.kdc101 import KDC101  # noqa: E402
from gelrig.drivers.kdc101.apt import AptFramer, MsgId, command, encode  # noqa: E402
from gelrig.instrument.core.clock import VirtualClock  # noqa: E402
from gelrig.simulators.kdc101 import KDC101Simulator, register  # noqa: E402

REQUEST = encode(command(MsgId.MOT_REQ_POSCOUNTER, 1))
REPLY_LEN = 12

ECHO_SERVER = """
import socket, sys
srv = socket.create_server(("127.0.0.1", 0))
print(srv.getsockname()[1], flush=True)
conn, _ = srv.accept()
conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
while data := conn.recv(4096):
    conn.sendall(data * 2)  # 6 bytes in, 12 out: the size of the APT exchange
"""


def rate(trip: Callable[[], object], n: int, repeats: int) -> float:
    """Median round trips per second over ``repeats`` runs of ``n`` trips."""
    for _ in range(min(n, 50)):
        trip()  # warm up
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            trip()
        rates.append(n / (time.perf_counter() - t0))
    return statistics.median(rates)


def apt_trip(port: serial.SerialBase) -> Callable[[], None]:
    framer = AptFramer()

    def trip() -> None:
        port.write(REQUEST)
        framer.feed(port.read(REPLY_LEN))
        msg = framer.next_message()
        if msg is None or msg.msg_id != MsgId.MOT_GET_POSCOUNTER:
            raise RuntimeError(f"bad reply {msg!r}")

    return trip


def start(args: list[str]) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True, cwd=ROOT)
    assert proc.stdout is not None
    return proc, proc.stdout.readline().strip()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--n", type=int, default=2000)
    opts = parser.parse_args()
    n, reps = opts.n, opts.repeats
    results: dict[str, float] = {}

    # Baseline: raw loopback TCP echo (socket module, no pyserial, no APT).
    echo, port_no = start([sys.executable, "-c", ECHO_SERVER])
    sock = socket.create_connection(("127.0.0.1", int(port_no)))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def echo_trip() -> None:
        sock.sendall(REQUEST)
        got = 0
        while got < REPLY_LEN:
            got += len(sock.recv(REPLY_LEN - got))

    results["baseline: raw loopback TCP echo"] = rate(echo_trip, n, reps)
    sock.close()
    echo.terminate()
    echo.wait()

    # In-process pyserial URL (virtual clock): simulator decode + answer, no OS I/O.
    clock = VirtualClock()
    url = register(KDC101Simulator(clock), "bench")
    with serial.serial_for_url(url, timeout=1.0) as port:
        results["APT via kdc101sim:// (in-process)"] = rate(apt_trip(port), n, reps)
    stage = KDC101(url, clock=clock).open()
    results["KDC101.position() via kdc101sim://"] = rate(stage.position, n, reps)
    stage.close()

    # TCP server in its own process, real clock, pyserial socket:// client.
    server, line = start([sys.executable, "-m", "gelrig.simulators.kdc101.serve", "--tcp",
                          "127.0.0.1:0", "--clock", "real"])
    address = line.rsplit(" ", 1)[-1]
    try:
        with serial.serial_for_url(address, timeout=1.0) as port:
            results["APT via TCP server (socket://)"] = rate(apt_trip(port), n // 2, reps)
        stage = KDC101(address).open()
        results["KDC101.position() via TCP server"] = rate(stage.position, n // 2, reps)
        stage.close()
    finally:
        server.terminate()
        server.wait()

    base = results["baseline: raw loopback TCP echo"]
    print(f"APT round trips per second (median of {reps} repeats)")
    for name, value in results.items():
        print(f"  {name:<38s} {value:>10.0f} /s   x{value / base:5.2f} of baseline")
    return 0


if __name__ == "__main__":
    sys.exit(main())
