"""The simulated USB-6001's counter: ctr0, 32-bit edge counting on PFI 0, read on demand.

The device's one counter counts edges on PFI 0 (User Guide: "Event Counter"; the USB-6008/6009
guide says falling edges only, the 6001's UNVERIFIED: both edges are accepted here); it counts
up from the initial count and rolls over at 2^32 (32-bit, spec sheet). Reads are software
timed: a sample clock is refused (-200077, On Demand only; UNVERIFIED). Any other counter
input measurement is refused with -200431, pulse generation with -200430: ctr0 is not an output
(Dev.CO.PhysicalChans is empty). Edges come from the twin's :class:`DigitalLines` PFI 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from nidaqmx.constants import CountDirection, Edge

from gelrig.simulators.usb6001.device import INVALID_ATTRIBUTE_VALUE, DaqmxError
from gelrig.simulators.usb6001.lines import DigitalLines
from gelrig.simulators.usb6001.ni_errors import INVALID_ROUTING_SOURCE

RISING, FALLING = Edge.RISING.value, Edge.FALLING.value
COUNT_UP = CountDirection.COUNT_UP.value
COUNTER_BITS = 32
COUNT_TERMINAL = "PFI0"


@dataclass
class EdgeCountChannel:
    name: str
    edge: int = RISING
    initial: int = 0
    direction: int = COUNT_UP
    terminal: str = COUNT_TERMINAL
    description: str = ""


@dataclass
class CounterTask:
    name: str
    channel: EdgeCountChannel | None = None
    running: bool = False
    t_start: float = math.inf

    def count(self, lines: DigitalLines, now: float) -> int:
        chan = self.channel
        assert chan is not None
        if not self.running:
            return chan.initial
        n = lines.pfi[chan.terminal].edges(self.t_start, now, chan.edge == RISING)
        return (chan.initial + n) % 2**COUNTER_BITS


def check_edge(edge: int) -> int:
    if edge not in (RISING, FALLING):
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_CI_CountEdges_ActiveEdge\n"
                         f"Requested Value: {edge}\nPossible Values: Rising ({RISING}), "
                         f"Falling ({FALLING})")
    return edge


def check_direction(direction: int) -> int:
    if direction != COUNT_UP:
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Property: DAQmx_CI_CountEdges_Dir\n"
                         f"Requested Value: {direction}\nPossible Values: Count Up "
                         f"({COUNT_UP})\nThe USB-6001's counter counts up only (UNVERIFIED).")
    return direction


def check_initial(count: int) -> int:
    if not 0 <= count < 2**COUNTER_BITS:
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Property: DAQmx_CI_CountEdges_InitialCnt\n"
                         f"Requested Value: {count}\nMaximum Value: {2**COUNTER_BITS - 1}")
    return count


def check_terminal(text: str, device: str) -> str:
    name = text.strip().lstrip("/").split("/")[-1].replace(" ", "")
    if name.upper() != COUNT_TERMINAL:
        raise DaqmxError(INVALID_ROUTING_SOURCE, f"Property: DAQmx_CI_CountEdges_Term\n"
                         f"Source Device: {device}\nSource Terminal: {text}\nThe USB-6001 "
                         f"counts edges on /{device}/PFI0 only.")
    return COUNT_TERMINAL
