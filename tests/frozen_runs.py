"""``gelrig run`` against instruments served as separate processes, one of them faulted mid-run.

The instrument under test is a ``gelrig sim serve`` process (KDC101 over ``socket://``,
USB-6001 over the NI gRPC Device Server API, MCR 501 over pyvisa TCP); :func:`frozen_run`
starts the run, waits until it records, then faults that instrument: ``freeze`` (SIGSTOP for
good), ``recover`` (SIGSTOP, SIGCONT a few seconds after the run's line) or ``drop`` (the
link through a :class:`~tests.faultproxy.FaultProxy` is cut while the instrument stays up
and accepts new clients), and times the way out: from the fault to the terminal's one line
(``...; details: RUN_DIR/gelrig.log``) and to the process's exit. ``inspect`` then reads the
served instrument directly, before it is torn down. Used by
``tests/gelrig/test_stop_reaches.py`` (bounds, outcomes) and
``benchmarks/bench_frozen_stop.py`` (medians for the README).
"""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gelrig.instrument.core.store import RunDirectory
from tests.faultproxy import FaultProxy
from tests.served import ROOT, Served, serve

COMPRESSION_RIG = """
[rig]
kind = "compression"
name = "KDC101 and USB-6001 served by other processes"
[stage]
transport = "serial"
address = "socket://127.0.0.1:{stage}"
[force]
transport = "grpc"
address = "grpc://127.0.0.1:{force}"
[force.chain]
rated_output = "2 mV/V"
excitation = "5 V"
gain = 1000
"""

#: A contact search that never finds contact (the served DAQ's plate stays still): the stage
#: probes in 0.5 mm moves, so it is moving or about to when the freeze comes.
COMPRESSION_PROTOCOL = """
[protocol]
name = "probe"
rig = "compression"
[[step]]
kind = "compression_contact_search"
start = "1 mm"
probe = "0.5 mm"
speed = "0.5 mm/s"
max_travel = "10 mm"
tare_time = "0.2 s"
"""

SHEAR_RIG = """
[rig]
kind = "shear"
name = "MCR 501 served by another process"
[rheometer]
transport = "visa"
address = "TCPIP0::127.0.0.1::{rheometer}::SOCKET"
arm = "27 mm"
max_speed = "5 mm/s"
overlap_limit = "1.2 mm"
"""

#: The arm turns through a sweep at a safe gap above the spheres, streaming its records.
SHEAR_PROTOCOL = """
[protocol]
name = "sweep"
rig = "shear"
[[step]]
kind = "shear_contact_search"
safe_gap = "4 mm"
coarse = "1 mm"
fine = "0.1 mm"
rpm = 1
threshold = "0.2 mN*m"
sweep = "70 mm"
"""


@dataclass
class FrozenRun:
    """How a run with one frozen instrument ended, timed from the freeze (wall s)."""

    instrument: str
    to_line: float
    to_exit: float
    line: str
    returncode: int
    output: str
    meta: dict[str, Any] = field(default_factory=dict)
    inspected: Any = None


def _reader(stream: Any, lines: queue.Queue[tuple[float, str]]) -> None:
    for text in iter(stream.readline, ""):
        lines.put((time.monotonic(), text.rstrip("\n")))


@contextlib.contextmanager
def served_rig(instrument: str, folder: Path, proxied: bool = False
               ) -> Iterator[tuple[Path, Path, Served, FaultProxy | None]]:
    """The rig file and protocol of ``instrument``'s rig with its instruments served, the
    served process of ``instrument`` (kdc101, usb6001 or mcr501), and with ``proxied`` the
    fault proxy the rig reaches it through."""
    with contextlib.ExitStack() as stack:
        if instrument == "mcr501":
            target = stack.enter_context(serve("mcr501"))
        else:
            stage = stack.enter_context(serve("kdc101"))
            force = stack.enter_context(serve("usb6001", "--first-touch", "20 mm"))
            target = stage if instrument == "kdc101" else force
        proxy = stack.enter_context(FaultProxy(target.port, lifetime=300)) if proxied else None
        port = proxy.port if proxy is not None else target.port
        if instrument == "mcr501":
            rig_text, protocol_text = SHEAR_RIG.format(rheometer=port), SHEAR_PROTOCOL
        else:
            rig_text = COMPRESSION_RIG.format(
                stage=port if instrument == "kdc101" else stage.port,
                force=port if instrument == "usb6001" else force.port)
            protocol_text = COMPRESSION_PROTOCOL
        rig, protocol = folder / "rig.toml", folder / "protocol.toml"
        rig.write_text(rig_text)
        protocol.write_text(protocol_text)
        yield rig, protocol, target, proxy


def frozen_run(instrument: str, folder: Path, fault: str = "freeze", recording: float = 1.5,
               limit: float = 90.0, thaw_after: float = 3.0, give_up_after: float | None = None,
               inspect: Callable[[Served], Any] | None = None) -> FrozenRun:
    """Run the protocol of ``instrument``'s rig, fault ``instrument`` (``freeze``,
    ``recover``: SIGCONT ``thaw_after`` s after the line, or ``drop``) once the run has
    recorded for ``recording`` s, and time the way out (at most ``limit`` s). With
    ``give_up_after`` a Ctrl-C that long after the line gives up the pending safe stop."""
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / "run"
    run = RunDirectory(out)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1", "COLUMNS": "400"}
    with served_rig(instrument, folder, proxied=fault == "drop") as (rig, protocol, target,
                                                                    proxy):
        proc = subprocess.Popen(
            [sys.executable, "-m", "gelrig.cli", "run", str(protocol), "--rig", str(rig),
             "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            stdin=subprocess.DEVNULL, env=env, cwd=folder)
        lines: queue.Queue[tuple[float, str]] = queue.Queue()
        readers = [threading.Thread(target=_reader, args=(stream, lines), daemon=True)
                   for stream in (proc.stdout, proc.stderr)]
        for reader in readers:
            reader.start()
        try:
            _wait(lambda: _recording(run), limit, proc)
            time.sleep(recording)
            if proxy is not None:
                proxy.drop()
            else:
                target.pause()
            frozen = time.monotonic()
            seen: list[str] = []
            line, at = "", 0.0
            end = frozen + limit
            while time.monotonic() < end and not line:
                with contextlib.suppress(queue.Empty):
                    t, text = lines.get(timeout=0.1)
                    seen.append(text)
                    if "details:" in text:
                        line, at = text, t
                if proc.poll() is not None and lines.empty() and not line:
                    break
            if fault == "recover":
                time.sleep(thaw_after)
                target.resume()
            elif give_up_after is not None and proc.poll() is None:
                time.sleep(give_up_after)
                proc.send_signal(signal.SIGINT)
            proc.wait(timeout=max(1.0, end - time.monotonic()))
            exited = time.monotonic()
            time.sleep(0.2)
            while not lines.empty():
                seen.append(lines.get()[1])
        finally:
            target.resume()
            if proc.poll() is None:
                proc.send_signal(signal.SIGKILL)
                proc.wait(30)
            for reader in readers:
                reader.join(timeout=5)
            for stream in (proc.stdout, proc.stderr):
                if stream is not None:
                    stream.close()
        inspected = inspect(target) if inspect is not None else None
    meta = run.read_metadata() if run.meta_path.is_file() else {}
    return FrozenRun(instrument, (at or exited) - frozen, exited - frozen, line,
                     proc.returncode, "\n".join(seen), meta, inspected)


def _recording(run: RunDirectory) -> bool:
    try:
        if run.read_metadata()["steps"][0]["status"] != "running":
            return False
        return bool(run.read_step(0)["t_s"].size > 10)
    except Exception:
        return False


def _wait(predicate: Any, timeout: float, proc: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        if proc.poll() is not None:
            raise AssertionError(f"gelrig run ended early with exit {proc.returncode}")
        time.sleep(0.1)
    raise AssertionError("the run did not start recording in time")
