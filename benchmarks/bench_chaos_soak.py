"""Chaos soak: short real protocols under random wire, process and disk faults (issue 32).

Run: ``.venv/bin/python benchmarks/bench_chaos_soak.py [--minutes 30] [--seed 32]``
(``--minutes 1`` is the quick mode; ``--keep DIR`` keeps every episode's folder, ``--faults
disk_full,...`` draws only those, ``--runs N`` stops after N runs).

Each episode serves its rig's instruments as separate ``gelrig sim serve`` processes on the
real clock (shear: the MCR 501; compression: the KDC101 and the USB-6001), reaches the moving
instrument through a :class:`~tests.faultproxy.FaultProxy`, starts ``gelrig run`` as a
subprocess and, once the run records, injects one fault drawn from a seeded schedule:

- wire: ``link_drop`` (cut, the instrument up), ``link_frozen`` (replies swallowed until the
  run ends; its pending stop is given up by a Ctrl-C 3 s after the line), ``link_recovered``
  (swallowed, relayed again 1-6 s later), ``garbage`` (replies replaced by noise for 2 s);
- process: ``gelrig_kill`` (SIGKILL of gelrig, then ``gelrig resume``), ``sim_kill``
  (SIGKILL of one instrument's server), ``sim_stop`` (SIGSTOP, SIGCONT 1-6 s later);
- disk: ``disk_full`` (the run folder on its own 16 MiB tmpfs, filled to ENOSPC while the run
  records; then the filler is removed and ``gelrig resume`` continues in place);
- ``none`` (a control run).

Afterwards it checks from outside, not by gelrig's word:

- **data lost**: samples (rows every column has) an outside reader saw flushed in the step
  files while the run went on (polled every 0.5 s), plus the samples run.json claims per
  step file, that are not in ``gelrig export --csv`` of the run folder afterwards (every
  step file, resumed attempts included; matched by ``t_s`` as exported, ``%.10g``). An
  export that fails loses all.
- **unverified stop**: a run that ended on a fault (exit 1 or 3) whose run.json ``safe_state``
  is not verified (neither at once nor ``completed_later``), or whose moving instrument, read
  directly right after the exit (pylablib for the KDC101, a raw socket for the MCR 501), is
  still moving. *Unreported* when gelrig claimed verified or printed none of ``NOT
  CONFIRMED``, ``NOT SENT``, ``STILL MOVING``, ``NOT COMPLETED``.
- **rig left loaded**: after the last gelrig process of the episode, the twin read directly
  is loaded: compression, the plate past the protocol's first touch (the served USB-6001 is
  not coupled to the stage, so position is what can be read); shear, a normal force above
  5 mN (the safe stop's loaded level). *Said unloaded* when the run completed or its safe
  stop claimed a verified retract or lift.
- exit codes outside 0-3 (the SIGKILL the soak itself sends aside), ``Traceback`` in any
  gelrig output, and a Ctrl-C that did not give up a pending safe stop (``link_frozen``).

Prints one line per episode and a table; exits 1 if data was lost, a stop was unverified
without being reported so, a rig was loaded while gelrig said unloaded, or a traceback, an
undocumented exit code, a hung process or a lost Ctrl-C was seen.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import os
import queue
import random
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.faultproxy import FaultProxy
from tests.frozen_runs import COMPRESSION_RIG, SHEAR_RIG
from tests.served import ROOT, Served, serve

FAULTS = ("none", "link_drop", "link_frozen", "link_recovered", "garbage", "gelrig_kill",
          "sim_kill", "sim_stop", "disk_full")
KINDS = {"none": "control", "link_drop": "wire", "link_frozen": "wire",
         "link_recovered": "wire", "garbage": "wire", "gelrig_kill": "process",
         "sim_kill": "process", "sim_stop": "process", "disk_full": "disk"}
WEIGHTS = (1, 2, 1, 2, 1, 2, 1, 2, 2)
DOCUMENTED_EXITS = {0, 1, 2, 3}
WARNINGS = ("NOT CONFIRMED", "NOT SENT", "STILL MOVING", "NOT COMPLETED")
LOADED_N = 5e-3  # the safe stop's loaded level (N)
FIRST_TOUCH_MM = 3.0  # the compression protocol's first touch
COUNTS_PER_MM = 34554.96  # the KDC101 twin's encoder scale
PROCESS_LIMIT_S = 150.0  # a gelrig process still running after this is killed: "hung"
SERVE_S = 900.0  # the servers end by themselves after this
MOTION_BOUND_S = 2.0  # a motion gelrig no longer renews ends within this (ADR 0201)

COMPRESSION_PROTOCOL = """
[protocol]
name = "soak compression"
rig = "compression"
[sample]
diameter = "18.63 mm"
[[step]]
kind = "ramp_hold"
name = "first hold"
first_touch = "3 mm"
strain = 0.02
strain_rate = "0.05 /s"
hold = "4 s"
tare_time = "0.2 s"
terms = 1
[[step]]
kind = "ramp_hold"
name = "second hold"
first_touch = "3 mm"
strain = 0.03
strain_rate = "0.05 /s"
hold = "4 s"
tare_time = "0.2 s"
terms = 1
"""

SHEAR_PROTOCOL = """
[protocol]
name = "soak shear"
rig = "shear"
[[step]]
kind = "speed_ladder"
touch_gap = "3 mm"
centre_angle = 0.8
overlaps = 1
first_overlap = "0.3 mm"
speeds = ["2 mm/s"]
travel = "8 mm"
wait = "1 s"
interval = "0.1 s"
"""

#: How long after recording starts a fault may come (s), per rig: within the run's motion
#: (compression: two steps, so that a disk filled in the first meets the second's new file;
#: a step's first 16,384 rows have their space from its first flush).
WINDOW_S = {"compression": 10.0, "shear": 12.0}


@dataclass
class Plan:
    """One episode's draws from the seeded schedule."""

    rig: str
    fault: str
    delay_s: float  # from the first recorded samples to the fault
    after_s: float  # recover after (link_recovered, sim_stop)
    target: str  # the served instrument a process fault hits


@dataclass
class Episode:
    """What one episode did and what was found from outside."""

    plan: Plan
    exits: list[int] = field(default_factory=list)
    to_line_s: float | None = None
    line: str = ""
    status: str = ""
    hit: bool = False  # the fault ended the run (not completed)
    observed: int = 0
    lost: int = 0
    lost_detail: str = ""
    unverified: bool = False
    unreported: bool = False
    loaded: bool | None = None
    said_unloaded: bool = False
    moving: bool | None = None
    kept_moving: bool = False  # still moving MOTION_BOUND_S after the first read
    ctrl_c_lost: bool = False  # a Ctrl-C sent to give up the pending stop was not honoured
    tracebacks: int = 0
    odd_exits: list[int] = field(default_factory=list)
    hung: bool = False
    folder: str = ""

    @property
    def bad(self) -> list[str]:
        """What makes this episode fail the soak."""
        problems = []
        if self.lost:
            problems.append(f"{self.lost} samples lost ({self.lost_detail})")
        if self.unreported:
            problems.append("unverified stop not reported")
        if self.loaded and self.said_unloaded:
            problems.append("left loaded while gelrig said unloaded")
        if self.tracebacks:
            problems.append("traceback")
        if self.odd_exits:
            problems.append(f"exit {self.odd_exits}")
        if self.hung:
            problems.append("hung")
        if self.kept_moving:
            problems.append("still moving after the motion bound")
        if self.ctrl_c_lost:
            problems.append("Ctrl-C did not give up the pending safe stop")
        return problems


def draw(rng: random.Random, faults: Sequence[str] = FAULTS) -> Plan:
    """The next episode of the schedule, its fault drawn from ``faults`` (weighted)."""
    rig = rng.choice(("compression", "shear"))
    fault = rng.choices(faults, weights=[WEIGHTS[FAULTS.index(f)] for f in faults])[0]
    target = "mcr501" if rig == "shear" else rng.choice(("kdc101", "usb6001"))
    return Plan(rig, fault, rng.uniform(0.0, WINDOW_S[rig]), rng.uniform(1.0, 6.0), target)


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1", "COLUMNS": "400"}


class Gelrig:
    """A ``gelrig`` subprocess whose output lines are timestamped as they come."""

    def __init__(self, argv: Sequence[str], cwd: Path):
        self.proc = subprocess.Popen([sys.executable, "-m", "gelrig.cli", *argv],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     stdin=subprocess.DEVNULL, env=_env(), cwd=cwd)
        self.lines: queue.Queue[tuple[float, str]] = queue.Queue()
        self.seen: list[tuple[float, str]] = []
        self._readers = [threading.Thread(target=self._read, args=(s,), daemon=True)
                         for s in (self.proc.stdout, self.proc.stderr)]
        for reader in self._readers:
            reader.start()

    def _read(self, stream: Any) -> None:
        for text in iter(stream.readline, ""):
            self.lines.put((time.monotonic(), text.rstrip("\n")))

    def pump(self, timeout: float = 0.1) -> None:
        with contextlib.suppress(queue.Empty):
            self.seen.append(self.lines.get(timeout=timeout))
            while True:
                self.seen.append(self.lines.get_nowait())

    def line_after(self, t0: float) -> tuple[float, str] | None:
        """The terminal's one line after ``t0``: ``...; details: ...`` or ``gelrig: ...``."""
        for t, text in self.seen:
            if t >= t0 and ("details:" in text or text.startswith("gelrig: ")):
                return t, text
        return None

    def finish(self, limit: float) -> tuple[int, bool]:
        """Wait (at most ``limit`` s) for the exit; the exit code and whether it hung."""
        end = time.monotonic() + limit
        while self.proc.poll() is None and time.monotonic() < end:
            self.pump()
        hung = self.proc.poll() is None
        if hung:
            self.proc.kill()
        self.proc.wait(30)
        for reader in self._readers:
            reader.join(timeout=5)
        self.pump(0.0)
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream is not None:
                stream.close()
        return self.proc.returncode, hung

    @property
    def output(self) -> str:
        return "\n".join(text for _, text in self.seen)


class Observer:
    """An outside reader polling the run's step files: every ``t_s`` it saw flushed."""

    def __init__(self, run: Path):
        from gelrig.instrument.core.store import RunDirectory

        self.run = RunDirectory(run)
        self.seen: dict[tuple[int, float], Any] = {}  # (step, first t) -> longest t_s seen
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def recording(self) -> bool:
        return any(len(t) > 10 for t in list(self.seen.values()))

    def _loop(self) -> None:
        from gelrig.instrument.core.store import read_step

        while not self._stop.wait(0.5):
            try:
                steps = self.run.read_metadata()["steps"]
            except Exception:
                continue
            for step in steps:
                try:  # a sample is a row every column has (what read_step returns)
                    t = read_step(self.run.step_file(step))["t_s"]
                except Exception:
                    continue
                if t.size:
                    key = (int(step["index"]), float(t[0]))
                    if key not in self.seen or t.size > len(self.seen[key]):
                        self.seen[key] = t

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10)


@contextlib.contextmanager
def small_disk(where: Path, size: str = "16m") -> Iterator[Path]:
    """A tmpfs of ``size`` at ``where`` (needs root); unmounted afterwards."""
    where.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"cannot mount a tmpfs at {where}: {done.stderr.strip()}")
    try:
        yield where
    finally:
        with contextlib.suppress(OSError):  # kept for a look afterwards (--keep)
            shutil.copytree(where / "run", where.with_name("run-from-disk"), symlinks=True)
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def fill(disk: Path) -> Path:
    """Fill ``disk`` to ENOSPC with one file; its path."""
    filler = disk / "filler"
    with contextlib.suppress(OSError), open(filler, "wb") as handle:
        block = b"\0" * (1 << 20)
        while True:
            handle.write(block)
            handle.flush()
    return filler


def can_mount() -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    with tempfile.TemporaryDirectory() as folder:
        try:
            with small_disk(Path(folder) / "m", "1m"):
                return True
        except RuntimeError:
            return False


# ---- the twins, read directly ----------------------------------------------------------------

def _until(attempt: Any, timeout: float) -> Any:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = attempt()
        if value is not None:
            return value
        time.sleep(0.1)
    return None


def read_mcr501(port: int) -> tuple[bool, float] | None:
    """(moving, normal force N) of the served MCR 501 over a raw socket, or None."""
    def attempt() -> tuple[bool, float] | None:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=2.0) as sock:
                handle = sock.makefile("rwb")

                def ask(request: str) -> str:
                    handle.write(request.encode() + b"\r\n")
                    handle.flush()
                    return handle.readline().decode().strip()

                status, force = ask(":STAT[?]"), ask(":FN[?]")
            if not status.startswith(":STAT[") or not force.startswith(":FN["):
                return None
            mode, flags = status[6:-1].split(";")
            moving = mode == "ROT" or bool(int(flags, 16) & 0x09)
            return moving, float(force[4:-1])
        except (OSError, ValueError):
            return None
    found: tuple[bool, float] | None = _until(attempt, 5.0)
    return found


def read_kdc101(port: int) -> tuple[bool, float] | None:
    """(moving, position mm) of the served KDC101 through pylablib, or None."""
    from pylablib.devices.Thorlabs import kinesis

    def attempt() -> tuple[bool, float] | None:
        motor = None
        try:
            motor = kinesis.KinesisMotor(("serial", f"socket://127.0.0.1:{port}"),
                                         scale="step")
            return bool(motor.is_moving()), float(motor.get_position()) / COUNTS_PER_MM
        except Exception:
            return None
        finally:
            if motor is not None:
                with contextlib.suppress(Exception):
                    motor.close()
    found: tuple[bool, float] | None = _until(attempt, 5.0)
    return found


def read_twin(rig: str, served: dict[str, Served]) -> tuple[bool | None, bool | None]:
    """(moving, loaded) of the rig's moving instrument, read directly; None: unreadable."""
    if rig == "shear":
        if served["mcr501"].proc.poll() is not None:
            return None, None
        got = read_mcr501(served["mcr501"].port)
        return (None, None) if got is None else (got[0], abs(got[1]) > LOADED_N)
    if served["kdc101"].proc.poll() is not None:
        return None, None
    stage = read_kdc101(served["kdc101"].port)
    return (None, None) if stage is None else (stage[0], stage[1] > FIRST_TOUCH_MM)


# ---- data lost ---------------------------------------------------------------------------

def exported(run: Path, out: Path) -> tuple[dict[str, set[float]], str]:
    """``gelrig export --csv`` of ``run`` into ``out``: t_s values per CSV stem, and the
    export's output (its exit code must be 0)."""
    done = subprocess.run([sys.executable, "-m", "gelrig.cli", "export", str(run), "--csv",
                           "--out", str(out)], capture_output=True, text=True, env=_env(),
                          timeout=300, stdin=subprocess.DEVNULL)
    if done.returncode != 0:
        return {}, f"export exit {done.returncode}: {done.stderr.strip()[-300:]}"
    times: dict[str, set[float]] = {}
    for path in out.glob("*.csv"):
        with open(path, newline="") as handle:
            rows = csv.reader(handle)
            header = next(rows, [])
            column = header.index("t_s") if "t_s" in header else 0
            times[path.stem] = {float(row[column]) for row in rows if row}
    return times, done.stdout + done.stderr


def data_lost(run: Path, out: Path, seen: dict[tuple[int, float], Any]
              ) -> tuple[int, int, str]:
    """(samples observed, samples lost, what) as the module docstring defines them."""
    times, text = exported(run, out)
    observed = sum(len(t) for t in seen.values())
    meta: dict[str, Any] = {}
    with contextlib.suppress(OSError, ValueError):
        meta = json.loads((run / "run.json").read_text())
    entries = [*meta.get("steps", []), *meta.get("interrupted_steps", [])]
    if not times and (observed or entries):
        claimed = sum(int(s.get("samples") or 0) for s in entries)
        return observed, max(observed, claimed), text
    by_step: dict[int, set[float]] = {}
    lost, what = 0, []
    for step in entries:
        stem = Path(step["file"]).stem
        have = times.get(stem, set())
        by_step.setdefault(int(step["index"]), set()).update(have)
        claimed = int(step.get("samples") or 0)
        if claimed > len(have):
            lost += claimed - len(have)
            what.append(f"{stem}: run.json says {claimed}, export has {len(have)}")
    for (index, _), t in seen.items():
        have = by_step.get(index, set())
        missing = sum(1 for value in t if float(f"{value:.10g}") not in have)
        if missing:
            lost += missing
            what.append(f"step {index}: {missing} of {len(t)} samples seen flushed missing")
    return observed, lost, "; ".join(what)


# ---- an episode ------------------------------------------------------------------------

def _safe_state(run: Path) -> tuple[str, dict[str, Any]]:
    try:
        meta = json.loads((run / "run.json").read_text())
    except (OSError, ValueError):
        return "", {}
    return str(meta.get("status", "")), dict(meta.get("safe_state") or {})


def _verified(safe: dict[str, Any]) -> tuple[bool, str]:
    later = safe.get("completed_later") or {}
    if later.get("verified"):
        return True, str(later.get("line", ""))
    return bool(safe.get("verified")), str(safe.get("line", ""))


def episode(plan: Plan, folder: Path) -> Episode:
    result = Episode(plan, folder=str(folder))
    with contextlib.ExitStack() as stack:
        served: dict[str, Served] = {}
        if plan.rig == "shear":
            served["mcr501"] = stack.enter_context(serve("mcr501", duration=SERVE_S))
            moving, rig_text, protocol_text = "mcr501", SHEAR_RIG, SHEAR_PROTOCOL
        else:
            served["kdc101"] = stack.enter_context(serve("kdc101", duration=SERVE_S))
            served["usb6001"] = stack.enter_context(
                serve("usb6001", "--first-touch", "20 mm", duration=SERVE_S))
            moving, rig_text, protocol_text = "kdc101", COMPRESSION_RIG, COMPRESSION_PROTOCOL
        proxy = FaultProxy(served[moving].port, lifetime=SERVE_S)
        stack.callback(proxy.stop)
        ports = {name: s.port for name, s in served.items()}
        ports[moving] = proxy.port
        rig = folder / "rig.toml"
        rig.write_text(rig_text.format(rheometer=ports.get("mcr501"),
                                       stage=ports.get("kdc101"), force=ports.get("usb6001")))
        protocol = folder / "protocol.toml"
        protocol.write_text(protocol_text)
        disk = (stack.enter_context(small_disk(folder / "disk"))
                if plan.fault == "disk_full" else folder)
        run = disk / "run"
        observer = Observer(run)
        stack.callback(observer.stop)
        gelrig = Gelrig(["run", str(protocol), "--rig", str(rig), "--out", str(run)], folder)
        start = time.monotonic()
        while (not observer.recording() and gelrig.proc.poll() is None
               and time.monotonic() - start < PROCESS_LIMIT_S):
            gelrig.pump()
        time.sleep(plan.delay_s)
        t_fault = time.monotonic()
        victim = served[plan.target]
        filler: Path | None = None
        if plan.fault == "link_drop":
            proxy.drop()
        elif plan.fault in ("link_frozen", "link_recovered"):
            proxy.swallow()
        elif plan.fault == "garbage":
            proxy.garbage()
        elif plan.fault == "gelrig_kill":
            gelrig.proc.send_signal(signal.SIGKILL)
        elif plan.fault == "sim_kill":
            victim.kill()
        elif plan.fault == "sim_stop":
            victim.pause()
        elif plan.fault == "disk_full":
            filler = fill(disk)
        healed = given_up = False
        end = t_fault + PROCESS_LIMIT_S
        while gelrig.proc.poll() is None and time.monotonic() < end:
            gelrig.pump()
            now = time.monotonic()
            line = gelrig.line_after(t_fault)
            if not healed and plan.fault == "link_recovered" and now > t_fault + plan.after_s:
                proxy.heal()
                healed = True
            if not healed and plan.fault == "garbage" and now > t_fault + 2.0:
                proxy.heal()
                healed = True
            if not healed and plan.fault == "sim_stop" and now > t_fault + plan.after_s:
                victim.resume()
                healed = True
            if (plan.fault == "link_frozen" and line is not None and not given_up
                    and now > line[0] + 3.0):
                gelrig.proc.send_signal(signal.SIGINT)
                given_up = True
        code, hung = gelrig.finish(max(1.0, end - time.monotonic()))
        line = gelrig.line_after(t_fault)
        result.to_line_s = (line[0] if line else time.monotonic()) - t_fault
        result.line = line[1] if line else ""
        outputs = [gelrig.output]
        (folder / "run.out").write_text(gelrig.output)
        result.exits.append(code)
        result.hung |= hung
        proxy.heal()
        if plan.fault == "sim_stop":
            victim.resume()
        status, safe = _safe_state(run)
        result.status = status
        result.hit = status != "completed"
        last = gelrig
        if plan.fault in ("gelrig_kill", "disk_full") and run.is_dir():
            if filler is not None:
                filler.unlink()
            last = Gelrig(["resume", str(run)], folder)
            code, hung = last.finish(PROCESS_LIMIT_S)
            result.exits.append(code)
            result.hung |= hung
            outputs.append(last.output)
            (folder / "resume.out").write_text(last.output)
            status, safe = _safe_state(run)
            result.status = status
        observer.stop()
        fault_ended = last.proc.returncode in (1, 3)
        claimed, safe_line = _verified(safe)
        proxy.stop()  # the twins' only client must be the reader now
        result.moving, result.loaded = read_twin(plan.rig, served)
        if result.moving:  # a motion gelrig no longer renews must end by itself
            time.sleep(MOTION_BOUND_S + 0.5)
            result.kept_moving = bool(read_twin(plan.rig, served)[0])
        text = "\n".join(outputs)
        result.ctrl_c_lost = given_up and "given up by Ctrl-C" not in text
        if fault_ended:
            result.unverified = not claimed or bool(result.moving)
            result.unreported = result.unverified and (
                (claimed and bool(result.moving)) or not any(w in text for w in WARNINGS))
        result.said_unloaded = last.proc.returncode == 0 or (
            claimed and ("retracted to" in safe_line or "lifted to" in safe_line))
        result.tracebacks = sum("Traceback" in o for o in outputs)
        killed = plan.fault == "gelrig_kill"
        result.odd_exits = [c for i, c in enumerate(result.exits)
                            if c not in DOCUMENTED_EXITS and not (killed and i == 0 and c == -9)]
        result.observed, result.lost, result.lost_detail = data_lost(run, folder / "csv",
                                                                     observer.seen)
    return result


# ---- the soak --------------------------------------------------------------------------

def soak(minutes: float, seed: int, work: Path, log: Any = print,
         faults: Sequence[str] = FAULTS, runs: int | None = None) -> list[Episode]:
    """Episodes until ``minutes`` of wall time have passed (the last one is finished) or
    ``runs`` episodes are done."""
    rng = random.Random(seed)
    disk_ok = can_mount()
    end = time.monotonic() + minutes * 60.0
    episodes: list[Episode] = []
    while time.monotonic() < end and (runs is None or len(episodes) < runs):
        plan = draw(rng, faults)
        if plan.fault == "disk_full" and not disk_ok:
            plan.fault = "none"
        folder = work / f"{len(episodes):03d}-{plan.rig}-{plan.fault}"
        folder.mkdir(parents=True)
        result = episode(plan, folder)
        episodes.append(result)
        exits = ",".join(str(c) for c in result.exits)
        to_line = f"{result.to_line_s:.1f} s" if result.hit and result.line else "-"
        log(f"{len(episodes):3d} {plan.rig:11s} {plan.fault:14s} @{plan.delay_s:4.1f}s "
            f"exit {exits:6s} {result.status:9s} line {to_line:>7s} "
            f"samples {result.observed:5d} lost {result.lost} moving {result.moving} "
            f"loaded {result.loaded}"
            + (f"  BAD: {'; '.join(result.bad)}" if result.bad else ""))
    return episodes


def report(episodes: Sequence[Episode], minutes: float, seed: int, wall_s: float) -> str:
    faults = Counter(e.plan.fault for e in episodes if e.plan.fault != "none")
    by_kind = Counter(KINDS[e.plan.fault] for e in episodes if e.plan.fault != "none")
    hits = [e.to_line_s for e in episodes if e.hit and e.line and e.to_line_s is not None]
    unverified = [e for e in episodes if e.unverified]
    loaded = [e for e in episodes if e.loaded]
    rows = [
        ("runs", f"{len(episodes)} ({sum(e.plan.rig == 'compression' for e in episodes)} "
                 f"compression, {sum(e.plan.rig == 'shear' for e in episodes)} shear; "
                 f"{sum(len(e.exits) for e in episodes)} gelrig run/resume processes)"),
        ("faults", f"{sum(faults.values())} ("
                   + ", ".join(f"{k} {n}" for k, n in sorted(by_kind.items())) + ")"),
        ("  by fault", ", ".join(f"{f} {faults[f]}" for f in FAULTS if faults[f])),
        ("runs ended by the fault", str(sum(e.hit for e in episodes if e.plan.fault != "none"))),
        ("samples seen flushed", str(sum(e.observed for e in episodes))),
        ("data lost (samples)", str(sum(e.lost for e in episodes))),
        ("unverified stops", f"{len(unverified)} "
                             f"({sum(e.unreported for e in episodes)} not reported as such)"),
        ("rigs left loaded", f"{len(loaded)} "
                             f"({sum(bool(e.said_unloaded) for e in loaded)} said unloaded)"),
        ("tracebacks", str(sum(e.tracebacks for e in episodes))),
        ("exit codes outside 0-3", str(sum(len(e.odd_exits) for e in episodes))),
        ("hung (> 150 s)", str(sum(e.hung for e in episodes))),
        ("Ctrl-C not honoured", str(sum(e.ctrl_c_lost for e in episodes))),
        ("fault -> exit line", "-" if not hits else
         f"median {statistics.median(hits):.1f} s, max {max(hits):.1f} s "
         f"({len(hits)} runs ended by a fault)"),
    ]
    width = max(len(name) for name, _ in rows)
    head = (f"chaos soak: --minutes {minutes:g} --seed {seed}, {wall_s / 60:.1f} min wall, "
            f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"load {os.getloadavg()[0]:.1f}")
    return "\n".join([head, *(f"  {name:<{width}}  {value}" for name, value in rows)])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0,
                        help="wall time to keep starting episodes (default 30)")
    parser.add_argument("--seed", type=int, default=32, help="seed of the fault schedule")
    parser.add_argument("--keep", type=Path, default=None,
                        help="keep every episode's folder under this directory")
    parser.add_argument("--faults", default=",".join(FAULTS),
                        help="comma-separated faults to draw from: " + ", ".join(FAULTS))
    parser.add_argument("--runs", type=int, default=None, help="stop after this many runs")
    args = parser.parse_args(argv)
    faults = tuple(args.faults.split(","))
    unknown = [f for f in faults if f not in FAULTS]
    if unknown:
        parser.error(f"--faults: unknown {', '.join(unknown)}; known: {', '.join(FAULTS)}")
    t0 = time.monotonic()
    with contextlib.ExitStack() as stack:
        if args.keep is None:
            work = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="soak-")))
        else:
            work = args.keep
            work.mkdir(parents=True, exist_ok=True)
        episodes = soak(args.minutes, args.seed, work, log=lambda s: print(s, flush=True),
                        faults=faults, runs=args.runs)
        print(report(episodes, args.minutes, args.seed, time.monotonic() - t0))
        bad = [e for e in episodes if e.bad]
        for e in bad:
            print(f"FAILED {Path(e.folder).name}: {'; '.join(e.bad)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
