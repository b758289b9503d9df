"""Run one of NI's shipped nidaqmx examples, unmodified, against the served simulated USB-6001.

The example's ``nidaqmx.Task()``, ``nidaqmx.system.System.local()`` and ``Device("Dev1")`` get
the served twin's gRPC session through nidaqmx's own interpreter selection (``grpc_options``
defaults to the twin's). ``input()`` (an example waiting for Enter) moves the virtual clock
on and returns. An example that loops until Ctrl+C gets a KeyboardInterrupt from its
``limit``-th read or write, as a user pressing Ctrl+C after a while. Nothing of the example's
file is changed: it is executed from its path with ``runpy`` as ``__main__``.
"""

from __future__ import annotations

import builtins
import contextlib
import io
import os
import runpy
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import nidaqmx
import nidaqmx.utils

from gelrig.instrument.core.clock import VirtualClock
from gelrig.simulators.usb6001 import SimulatedUsb6001, start_server
from gelrig.simulators.usb6001.signals import ConstantSignal
from gelrig.simulators.usb6001.subsystems import io_of

EXAMPLES = Path(__file__).parent / "ni_examples"


@dataclass
class Outcome:
    """How an example ended: ``code`` None if it ran to its end, else the DAQmx error code."""

    code: int | None
    output: str
    error: BaseException | None = None
    #: the twin afterwards: the level of each DIO line, the volts on ao0 and ao1
    lines: tuple[bool, ...] = ()
    ao: tuple[float, ...] = ()


@contextlib.contextmanager
def served_twin(clock: VirtualClock) -> Iterator[tuple[SimulatedUsb6001, Any]]:
    device = SimulatedUsb6001(clock, {f"ai{i}": ConstantSignal(0.5 * i, noise_rms=0.5e-3,
                                                               seed=i) for i in range(8)})
    server = start_server(device)
    channel = server.channel()
    try:
        yield device, nidaqmx.GrpcSessionOptions(grpc_channel=channel, session_name="")
    finally:
        channel.close()
        server.stop()


def run_example(relative: str, workdir: Path, limit: int | None = None,
                enter_after: float = 2.0) -> Outcome:
    """Run ``ni_examples/<relative>`` on a fresh twin; return how it ended."""
    clock = VirtualClock()
    path = EXAMPLES / relative
    with served_twin(clock) as (device, options):
        io_of(device).lines.square_wave("PFI0", 1000.0, start=0.25)  # a trigger / edges
        original = nidaqmx.utils._select_interpreter

        def select(grpc_options: Any = None, interpreter: Any = None) -> Any:
            return original(grpc_options or options, interpreter)

        def enter(prompt: str = "") -> str:
            print(prompt, end="")
            clock.advance(enter_after)
            time.sleep(0.2)  # let event callbacks (real threads) see the new samples
            return ""

        calls = {"n": 0}
        patches: list[tuple[Any, str, Any]] = [(nidaqmx.utils, "_select_interpreter", select),
                                               (builtins, "input", enter)]
        if limit is not None:
            for name in ("read", "write"):
                method = getattr(nidaqmx.Task, name)

                def counted(self: Any, *a: Any, __m: Any = method, **k: Any) -> Any:
                    calls["n"] += 1
                    if calls["n"] > limit:
                        raise KeyboardInterrupt
                    return __m(self, *a, **k)

                patches.append((nidaqmx.Task, name, counted))
        saved = [(obj, name, getattr(obj, name)) for obj, name, _ in patches]
        out = io.StringIO()
        cwd = Path.cwd()
        twin = io_of(device)

        def state() -> dict[str, Any]:
            return {"lines": tuple(twin.lines.level(i) for i in range(13)),
                    "ao": (twin.ao.volts(0), twin.ao.volts(1))}

        try:
            for obj, name, value in patches:
                setattr(obj, name, value)
            os.chdir(workdir)
            with contextlib.redirect_stdout(out):
                runpy.run_path(str(path), run_name="__main__")
            return Outcome(None, out.getvalue(), **state())
        except nidaqmx.errors.DaqError as exc:
            return Outcome(exc.error_code, out.getvalue(), exc, **state())
        finally:
            os.chdir(cwd)
            for obj, name, value in saved:
                setattr(obj, name, value)
