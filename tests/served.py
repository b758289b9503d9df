"""``gelrig sim serve NAME`` as a subprocess on a free loopback port, for fault tests.

The server is started with ``--duration`` (it ends by itself), read for the address it
prints (bounded wait), and in teardown continued (if stopped) and killed.
"""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_ADDRESS = re.compile(r"(127\.0\.0\.1):(\d+)")
START_TIMEOUT_S = 30.0


@dataclass
class Served:
    """A running simulator server process and where it listens."""

    proc: subprocess.Popen[str]
    host: str
    port: int

    def pause(self) -> None:
        """SIGSTOP: the process freezes, its sockets stay open (a hung instrument).

        Returns once the process is stopped (state T), waiting at most a second.
        """
        self.proc.send_signal(signal.SIGSTOP)
        end = time.monotonic() + 1.0
        while self._state() not in ("T", "t", "") and time.monotonic() < end:
            time.sleep(0.005)

    def _state(self) -> str:
        try:
            stat = Path(f"/proc/{self.proc.pid}/stat").read_text()
        except OSError:
            return ""
        return stat.rsplit(")", 1)[1].split()[0]

    def resume(self) -> None:
        self.proc.send_signal(signal.SIGCONT)

    def kill(self) -> None:
        """SIGKILL and reap (a crashed or unplugged instrument)."""
        self.resume()
        self.proc.kill()
        self.proc.wait(timeout=10)


@contextmanager
def serve(name: str, *options: str, duration: float = 120.0) -> Iterator[Served]:
    """Run ``gelrig sim serve name --port 0 ...`` (kdc101: ``--tcp 127.0.0.1:0``)."""
    where = ["--tcp", "127.0.0.1:0"] if name == "kdc101" else ["--host", "127.0.0.1",
                                                               "--port", "0"]
    argv = [sys.executable, "-m", "gelrig.cli", "sim", "serve", name, *where,
            "--duration", str(duration), *options]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, env=env)
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], START_TIMEOUT_S)
        line = proc.stdout.readline() if ready else ""
        match = _ADDRESS.search(line)
        if match is None:
            proc.kill()
            err = proc.stderr.read() if proc.stderr else ""
            raise RuntimeError(f"gelrig sim serve {name} did not start: {line!r} {err}")
        yield Served(proc, match[1], int(match[2]))
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGCONT)
            proc.kill()
        proc.wait(timeout=10)
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
