"""The rest of the simulated USB-6001 beside its analog input: AO, DIO, ctr0 and start
triggers, kept per device and per task name (docs/decisions/0290).

``io_of(device)`` is the device's :class:`Usb6001Io`: the twin reads what
the outputs do (``io.ao.volts(0)``, ``io.lines.level("port0/line3")``) and drives the inputs
(``io.lines.set_input(...)``, ``io.lines.pulse("PFI0", t)``, ``io.lines.square_wave(...)``,
``io.lines.wire("port0/line0", "PFI0")``). A DAQmx task is an AI task (the device's
:class:`SimTask`) or one of these; channels of two types in one task answer -200559.
"""

from __future__ import annotations

import math
import threading
import weakref
from typing import TypeAlias, TypeVar

from gelrig.simulators.usb6001.ao import AnalogOutput, AOTask
from gelrig.simulators.usb6001.counter import CounterTask
from gelrig.simulators.usb6001.device import (
    WAIT_UNTIL_DONE_DOES_NOT_INDICATE_DONE,
    DaqmxError,
    SimulatedUsb6001,
)
from gelrig.simulators.usb6001.dio import DigitalTask
from gelrig.simulators.usb6001.lines import DigitalLines
from gelrig.simulators.usb6001.ni_errors import MULTI_CHAN_TYPES_IN_TASK
from gelrig.simulators.usb6001.tdms_log import TdmsLogger
from gelrig.simulators.usb6001.triggers import AI_START, DIGITAL_EDGE, StartTrigger

IoTask: TypeAlias = AOTask | DigitalTask | CounterTask
T = TypeVar("T", AOTask, DigitalTask, CounterTask)

_IO: weakref.WeakKeyDictionary[SimulatedUsb6001, Usb6001Io] = weakref.WeakKeyDictionary()
_IO_LOCK = threading.Lock()


def io_of(device: SimulatedUsb6001) -> Usb6001Io:
    """The AO / DIO / counter / trigger side of ``device`` (one per device)."""
    with _IO_LOCK:
        io = _IO.get(device)
        if io is None:
            io = _IO[device] = Usb6001Io(device)
        return io


def _kind(task: IoTask) -> str:
    if isinstance(task, AOTask):
        return "analog output"
    if isinstance(task, DigitalTask):
        return "digital output" if task.output else "digital input"
    return "counter input"


class Usb6001Io:
    """Tasks that are not AI, the AO, the lines and PFI terminals, the start triggers."""

    def __init__(self, device: SimulatedUsb6001):
        self.device = device
        self.clock = device.clock
        self.lines = DigitalLines()
        self.ao = AnalogOutput(device.clock)
        self.logging = TdmsLogger()
        self.tasks: dict[str, IoTask] = {}
        self.triggers: dict[str, StartTrigger] = {}
        self._started: dict[str, float] = {}  # triggered task -> when it was started
        self._lock = threading.RLock()
        self.lines.listeners.append(self._edge)

    # --- task registry ---------------------------------------------------------------------

    def get(self, name: str) -> IoTask | None:
        with self._lock:
            self._forget_cleared()
            return self.tasks.get(name)

    def claim(self, name: str, new: T) -> T:
        """The task's io part of ``new``'s type, made if it has none: -200559 if the task
        holds channels of another type."""
        ai = self.device.task(name)  # -200088 if there is no such task
        with self._lock:
            self._forget_cleared()
            have = self.tasks.get(name)
            if have is not None and not _has_channels(have):
                have = None  # a create that failed left it empty: start afresh
            if ai.channels or (have is not None and (type(have) is not type(new) or (
                    isinstance(have, DigitalTask) and isinstance(new, DigitalTask)
                    and have.output != new.output))):
                held = "analog input" if ai.channels else _kind(have)  # type: ignore[arg-type]
                raise DaqmxError(MULTI_CHAN_TYPES_IN_TASK, f"Task Name: {name}\nThe task has "
                                 f"{held} channels; a {_kind(new)} channel cannot join them.")
            if have is None:
                self.tasks[name] = new
                return new
            return have

    def check_ai(self, name: str) -> None:
        """An AI channel may join the task only if it has no channel of another type."""
        have = self.get(name)
        if have is not None and _has_channels(have):
            raise DaqmxError(MULTI_CHAN_TYPES_IN_TASK, f"Task Name: {name}\nThe task has "
                             f"{_kind(have)} channels; an analog input channel cannot join them.")

    def _forget_cleared(self) -> None:
        gone = [n for n in self.tasks if not self.device.has_task(n)]
        for n in gone:
            self._drop(n)

    def _drop(self, name: str) -> None:
        task = self.tasks.pop(name, None)
        if isinstance(task, AOTask):
            self.ao.stop(task)
        self.triggers.pop(name, None)
        self._started.pop(name, None)
        self.logging.forget(name)

    def clear(self, name: str) -> None:
        with self._lock:
            self._drop(name)

    # --- start, stop, done --------------------------------------------------------------------

    def start(self, name: str) -> None:
        task = self.tasks[name]
        if isinstance(task, AOTask):
            trig = self.triggers.get(name)
            task.start_gate = self._gate(name, trig) if trig and trig.kind == DIGITAL_EDGE \
                else None
            self.ao.start(task)
        elif isinstance(task, CounterTask):
            if not task.running:
                task.t_start = self.clock.now()
            task.running = True
        else:
            task.running = True

    def stop(self, name: str) -> None:
        task = self.tasks[name]
        if isinstance(task, AOTask):
            self.ao.stop(task)
        else:
            task.running = False
        self._started.pop(name, None)

    def is_done(self, name: str) -> bool:
        task = self.tasks[name]
        return self.ao.is_done(task) if isinstance(task, AOTask) else True

    def wait_until_done(self, name: str, timeout: float) -> None:
        task = self.tasks[name]
        if not isinstance(task, AOTask) or self.ao.is_done(task):
            return
        now = self.clock.now()
        end = task.end_time() + 1.0 / task.rate
        limit = math.inf if timeout < 0 else now + timeout
        if end <= limit:
            self.clock.sleep_until(end)
            self.ao.is_done(task)  # raises if the generation failed meanwhile
            return
        if math.isfinite(limit):
            self.clock.sleep_until(limit)
        forever = "" if math.isfinite(end) else "\nA continuous generation is never done."
        raise DaqmxError(WAIT_UNTIL_DONE_DOES_NOT_INDICATE_DONE,
                         f"Task Name: {name}\nTimeout: {timeout} s{forever}")

    def reset(self) -> None:
        """Reset Device: tasks stop, the AO goes to 0 V, every line is an input again."""
        with self._lock:
            for name in list(self.tasks):
                self.stop(name)
            self.ao.reset()
            self.lines.release_all()

    # --- start triggers -------------------------------------------------------------------

    def trigger(self, name: str) -> StartTrigger:
        self.device.task(name)
        with self._lock:
            return self.triggers.setdefault(name, StartTrigger())

    def arm_ai(self, name: str) -> None:
        """Give the AI task the gate of its start trigger (or none)."""
        trig = self.triggers.get(name)
        task = self.device.task(name)
        task.start_gate = self._gate(name, trig) if trig and trig.kind == DIGITAL_EDGE else None

    def _gate(self, name: str, trig: StartTrigger):  # type: ignore[no-untyped-def]
        def gate(start: float) -> float:
            self._started[name] = start
            return trig.first_edge(self.lines, start)
        return gate

    def ai_started(self, t0: float) -> None:
        """An AI task started (its first sample at ``t0``): AO tasks waiting for the AI start
        trigger start with it."""
        if math.isinf(t0):
            return
        with self._lock:
            waiting = list(self._started.items())
        for name, start in waiting:
            trig, task = self.triggers.get(name), self.tasks.get(name)
            if (trig is not None and trig.source == AI_START and isinstance(task, AOTask)
                    and task.running and math.isinf(task.t0)):
                task.t0 = trig.first_edge(self.lines, start, ai_start=t0)

    def _edge(self, terminal: str, t: float) -> None:
        """An edge was added on ``terminal``: tasks waiting for it start."""
        with self._lock:
            waiting = list(self._started.items())
        for name, start in waiting:
            trig = self.triggers.get(name)
            if trig is None or trig.source != terminal:
                continue
            first = trig.first_edge(self.lines, start)
            io = self.tasks.get(name)
            if isinstance(io, AOTask):
                if io.running and math.isinf(io.t0):
                    io.t0 = first
            elif self.device.has_task(name):
                with self.device._lock:  # the AI task's start, as _start sets it
                    ai = self.device.task(name)
                    started = ai.running and math.isinf(ai.t0)
                    if started:
                        ai.t0 = first
                if started:
                    self.ai_started(first)


def _has_channels(task: IoTask) -> bool:
    if isinstance(task, CounterTask):
        return task.channel is not None
    return bool(task.channels)
