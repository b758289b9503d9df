"""TDMS logging of the simulated USB-6001's AI tasks (DAQmx Configure Logging), written with
``nptdms``: one group (the group name given, else the task's name), one channel per AI
channel, volts as float64, with the waveform properties NI writes (``wf_increment``,
``wf_start_offset``, ``wf_samples``, ``unit_string``; the names are NI's TDMS waveform
properties, their full set as NI-DAQmx writes it is UNVERIFIED).

Log and Read: every read's samples are appended to the file as they are read. Log: reads
answer -201301, and what the task acquired is written when the task is stopped or waited on
(``flush``), as DAQmx streams it to disk. Logging needs a buffered (clocked) task: an on-demand
task answers -201299; an output task -201332. Operations: Create (the file must not exist),
Create or Replace, Open (it must exist), Open or Create (append); refusals -200077
(UNVERIFIED: DAQmx's own codes for a file that exists or does not).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from nidaqmx.constants import LoggingMode, LoggingOperation

from gelrig.instrument.physics.contact import FloatArray
from gelrig.simulators.usb6001.device import (
    INVALID_ATTRIBUTE_VALUE,
    DaqmxError,
    SimTask,
)
from gelrig.simulators.usb6001.ni_errors import (
    LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED,
    READ_NOT_SUPPORTED_FOR_LOGGING_MODE,
)

OFF, LOG, LOG_AND_READ = (LoggingMode.OFF.value, LoggingMode.LOG.value,
                          LoggingMode.LOG_AND_READ.value)
OPEN, OPEN_OR_CREATE = LoggingOperation.OPEN.value, LoggingOperation.OPEN_OR_CREATE.value
CREATE_OR_REPLACE, CREATE = (LoggingOperation.CREATE_OR_REPLACE.value,
                             LoggingOperation.CREATE.value)


@dataclass
class LogSetup:
    path: str
    mode: int
    group: str
    operation: int
    opened: bool = False  # the file was made ready (created, replaced, checked)


class TdmsLogger:
    """The logging set-up of each AI task and the files it writes."""

    def __init__(self) -> None:
        self.setups: dict[str, LogSetup] = {}
        self._lock = threading.Lock()

    def configure(self, task: SimTask, path: str, mode: int, group: str,
                  operation: int) -> None:
        if mode not in (OFF, LOG, LOG_AND_READ):
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_Logging_Mode\n"
                             f"Requested Value: {mode}")
        if operation not in (OPEN, OPEN_OR_CREATE, CREATE_OR_REPLACE, CREATE):
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_Logging_TDMS_Operation"
                             f"\nRequested Value: {operation}")
        with self._lock:
            if mode == OFF:
                self.setups.pop(task.name, None)
                return
            if not task.timing_set:
                raise DaqmxError(LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED,
                                 f"Task Name: {task.name}")
            if not path:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Property: DAQmx_Logging_FilePath\n"
                                 "Requested Value: (empty)")
            self.setups[task.name] = LogSetup(path, mode, group or task.name, operation)

    def setup(self, name: str) -> LogSetup | None:
        with self._lock:
            return self.setups.get(name)

    def check_read(self, name: str) -> None:
        """A read of a task that logs only: -201301."""
        setup = self.setup(name)
        if setup is not None and setup.mode == LOG:
            raise DaqmxError(READ_NOT_SUPPORTED_FOR_LOGGING_MODE, f"Task Name: {name}\n"
                             f"File: {setup.path}", samps_read=0)

    def append(self, task: SimTask, data: FloatArray, first: int) -> None:
        """Log ``data`` (channels x n), samples ``first ..`` of ``task``."""
        setup = self.setup(task.name)
        if setup is None or data.shape[1] == 0:
            return
        from nptdms import ChannelObject, GroupObject, TdmsWriter

        path = Path(setup.path)
        with self._lock:
            mode = "a"
            if not setup.opened:
                exists = path.exists()
                if setup.operation == CREATE and exists:
                    raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"TDMS file exists: {path}\n"
                                     "Logging operation: Create", samps_read=0)
                if setup.operation == OPEN and not exists:
                    raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"TDMS file not found: {path}\n"
                                     "Logging operation: Open", samps_read=0)
                if setup.operation in (CREATE, CREATE_OR_REPLACE) or not exists:
                    mode = "w"
                setup.opened = True
            dt = 1.0 / task.true_rate
            objects: list[object] = [GroupObject(setup.group)]
            for row, chan in zip(data, task.channels, strict=True):
                objects.append(ChannelObject(setup.group, chan.name, np.asarray(row, float), {
                    "unit_string": "Volts", "wf_increment": dt,
                    "wf_start_offset": 0.0 if math.isinf(task.t0) else first * dt,
                    "wf_samples": int(data.shape[1]),
                    "NI_ChannelName": chan.name}))
            with TdmsWriter(str(path), mode=mode) as writer:
                writer.write_segment(objects)

    def forget(self, name: str) -> None:
        with self._lock:
            self.setups.pop(name, None)
