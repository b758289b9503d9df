"""The simulated USB-6001's digital I/O tasks: static (on-demand) lines and ports.

P0.0-7, P1.0-3 and P2.0 are static DIO: every DI sample and DO update is software-timed
(User Guide). A DI or DO task is on demand; a sample clock on it is refused with DAQmx
-200077 naming the only timing type the device has for it, On Demand. A channel is one line
(``LineGrouping.CHAN_PER_LINE``) or a group of lines (``CHAN_FOR_ALL_LINES``); as a number,
a channel within one port has line n in bit n, a channel spanning ports has its lines in
order from bit 0 (UNVERIFIED for spanning channels). Line names that do not exist answer
-200170 naming the lines that do.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from nidaqmx.constants import LineGrouping

from gelrig.simulators.usb6001.device import (
    CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING,
    INVALID_ATTRIBUTE_VALUE,
    PHYSICAL_CHAN_DOES_NOT_EXIST,
    DaqmxError,
    add_named,
)
from gelrig.simulators.usb6001.lines import PORT_LINES, DigitalLines, line_index, line_name

CHAN_PER_LINE = LineGrouping.CHAN_PER_LINE.value
CHAN_FOR_ALL_LINES = LineGrouping.CHAN_FOR_ALL_LINES.value
ON_DEMAND_TIMING, SAMPLE_CLOCK_TIMING = 10390, 10388

_LINES = re.compile(r"^\s*/?(?P<dev>[^/\s]+)/port(?P<p>\d+)(?::(?P<q>\d+))?"
                    r"(?:/line(?P<a>\d+)(?::(?P<b>\d+))?)?\s*$", re.IGNORECASE)


@dataclass
class DigitalChannel:
    name: str
    lines: list[int]  # global line indices, in the channel's order
    description: str = ""

    @property
    def bits(self) -> list[int]:
        """Bit of each line in the channel's number (see the module's docstring)."""
        ports = {line_name(i).split("/")[0] for i in self.lines}
        if len(ports) == 1:
            return [int(line_name(i).split("line")[1]) for i in self.lines]
        return list(range(len(self.lines)))


@dataclass
class DigitalTask:
    name: str
    output: bool  # DO task (else DI)
    channels: list[DigitalChannel] = field(default_factory=list)
    running: bool = False

    @property
    def num_lines(self) -> int:
        return max((len(c.lines) for c in self.channels), default=0)


def all_lines(device: str) -> str:
    return ", ".join(f"{device}/{line_name(i)}" for i in range(sum(PORT_LINES)))


def parse_lines(text: str, device: str, check_device: object) -> list[tuple[str, list[int]]]:
    """``Dev1/port0/line0:3, Dev1/port1`` -> [(entry, [line indices])]; -200170 if absent."""
    out: list[tuple[str, list[int]]] = []
    for part in text.split(","):
        m = _LINES.match(part)
        if m is None:
            raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST,
                             f"Physical Channel Name: {part.strip()}\nPossible Values: "
                             f"{all_lines(device)}")
        check_device(m["dev"])  # type: ignore[operator]
        p, q = int(m["p"]), int(m["q"] if m["q"] is not None else m["p"])
        indices: list[int] = []
        for port in range(p, q + 1):
            if port >= len(PORT_LINES) or (m["q"] is not None and m["a"] is not None):
                raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST,
                                 f"Physical Channel Name: {part.strip()}\nPossible Values: "
                                 f"{device}/port0, {device}/port1, {device}/port2, "
                                 f"{all_lines(device)}")
            if m["a"] is None:
                indices += [line_index(port, i) for i in range(PORT_LINES[port])]
                continue
            a = int(m["a"])
            b = int(m["b"]) if m["b"] is not None else a
            step = 1 if b >= a else -1
            for i in range(a, b + step, step):
                if i >= PORT_LINES[port]:
                    raise DaqmxError(PHYSICAL_CHAN_DOES_NOT_EXIST,
                                     f"Physical Channel Name: {device}/port{port}/line{i}\n"
                                     f"Possible Values: {all_lines(device)}")
                indices.append(line_index(port, i))
        out.append((part.strip(), indices))
    return out


def add_channels(task: DigitalTask, text: str, names: str, grouping: int, device: str,
                 check_device: object) -> None:
    if task.running:
        raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
    if grouping not in (CHAN_PER_LINE, CHAN_FOR_ALL_LINES):
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Line Grouping: {grouping}\nPossible "
                         f"Values: One Channel For Each Line ({CHAN_PER_LINE}), One Channel "
                         f"For All Lines ({CHAN_FOR_ALL_LINES})")
    entries = parse_lines(text, device, check_device)
    if grouping == CHAN_FOR_ALL_LINES:
        lines = [i for _, idx in entries for i in idx]
        chans = [DigitalChannel(names or _group_name(text), lines)]
    else:
        lines = [i for _, idx in entries for i in idx]
        given = [n.strip() for n in names.split(",")] if names else []
        if given and len(given) != len(lines):
            given = [f"{names}{k}" for k in range(len(lines))]
        chans = [DigitalChannel(given[k] if given else f"{device}/{line_name(i)}", [i])
                 for k, i in enumerate(lines)]
    add_named(task.channels, chans)


def _group_name(text: str) -> str:
    """DAQmx's name of a channel of several lines given no name: the lines as written if they
    are one entry (``Dev1/port0``), else the first line and "..." (``Dev1/port0/line0...``)."""
    from nidaqmx.utils import unflatten_channel_string

    entries = unflatten_channel_string(text)
    return text.strip() if len(entries) == 1 else f"{entries[0]}..."


def refuse_sample_clock(task: DigitalTask) -> DaqmxError:
    """What DAQmx answers a sample clock on the 6001's static DIO: -200077."""
    kind = "digital output" if task.output else "digital input"
    return DaqmxError(INVALID_ATTRIBUTE_VALUE,
                      f"Property: DAQmx_SampTimingType\nRequested Value: Sample Clock\n"
                      f"Possible Values: On Demand\nThe USB-6001's {kind} lines are static: "
                      f"software-timed (on demand) only.\nTask Name: {task.name}")


def read_lines(task: DigitalTask, lines: DigitalLines) -> list[list[bool]]:
    """One sample: the level of every line of every channel."""
    return [lines.read(c.lines) for c in task.channels]


def read_numbers(task: DigitalTask, lines: DigitalLines) -> list[int]:
    out = []
    for chan, levels in zip(task.channels, read_lines(task, lines), strict=True):
        out.append(sum(1 << b for b, v in zip(chan.bits, levels, strict=True) if v))
    return out


def write_numbers(task: DigitalTask, lines: DigitalLines, values: list[int], t: float) -> None:
    """One DO update: each channel's lines take the bits of its number."""
    for chan, value in zip(task.channels, values, strict=True):
        lines.drive(chan.lines, [bool((int(value) >> b) & 1) for b in chan.bits], t)


def write_levels(task: DigitalTask, lines: DigitalLines, levels: list[list[bool]],
                 t: float) -> None:
    for chan, chan_levels in zip(task.channels, levels, strict=True):
        lines.drive(chan.lines, chan_levels[:len(chan.lines)], t)
