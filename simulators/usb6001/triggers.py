"""Start triggers of the simulated USB-6001: a digital edge on PFI 0 or PFI 1 starts an AI or
AO task; analog and reference triggers, which the device lacks, are refused.

The USB-6001 User Guide: "You can configure PFI 0 or PFI 1 as the AI Start Trigger" and the AO
"DAC Control ... startup condition, which could be triggered by PFI 0 or PFI 1". A started,
triggered task takes its first sample at the first active edge at or after its start (a
known edge: a pulse or square wave the twin put on the terminal, or a DO line wired to it);
until an edge comes, it acquires or generates nothing, and a read waits (and times out with
-200284). Refusals: an analog start trigger -200077 on Start.TrigType (possible values: Digital
Edge, None), any reference trigger -200077 on RefTrig.TrigType (None), retriggering -200452,
a source other than PFI 0/1 -89120 (codes UNVERIFIED against a real 6001).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from nidaqmx.constants import Edge, TriggerType

from gelrig.simulators.usb6001.device import (
    ATTRIBUTE_NOT_SUPPORTED_IN_TASK_CONTEXT,
    INVALID_ATTRIBUTE_VALUE,
    DaqmxError,
)
from gelrig.simulators.usb6001.lines import PFI_TERMINALS, DigitalLines
from gelrig.simulators.usb6001.ni_errors import INVALID_ROUTING_SOURCE

DIGITAL_EDGE, NO_TRIGGER = TriggerType.DIGITAL_EDGE.value, TriggerType.NONE.value
RISING, FALLING = Edge.RISING.value, Edge.FALLING.value


@dataclass
class StartTrigger:
    """A task's start trigger (type None until configured)."""

    kind: int = NO_TRIGGER
    source: str = "PFI0"
    edge: int = RISING

    def first_edge(self, lines: DigitalLines, after: float, ai_start: float = math.inf
                   ) -> float:
        """When the task starts if started at ``after``: at once without a trigger, else at
        the first active edge (``ai_start``: when the AI starts, for ``ai/StartTrigger``)."""
        if self.kind != DIGITAL_EDGE:
            return after
        if self.source == AI_START:
            return ai_start if ai_start >= after else math.inf
        return lines.pfi[self.source].first_edge(after, self.edge == RISING)


#: the AI start trigger as a source: the AO starts with the AI (an internal route)
AI_START = "ai/StartTrigger"


def check_source(text: str, device: str, output: bool = False) -> str:
    """PFI0 / PFI1, or (for the AO) the AI start trigger; else -89120."""
    parts = text.strip().strip("/").split("/")
    if output and [p.lower() for p in parts[-2:]] == ["ai", "starttrigger"]:
        return AI_START
    name = parts[-1].replace(" ", "").upper()
    if name not in PFI_TERMINALS:
        raise DaqmxError(INVALID_ROUTING_SOURCE, f"Property: DAQmx_DigEdge_StartTrig_Src\n"
                         f"Source Device: {device}\nSource Terminal: {text}\nThe USB-6001 "
                         f"takes a start trigger on /{device}/PFI0 or /{device}/PFI1.")
    return name


def check_edge(edge: int) -> int:
    if edge not in (RISING, FALLING):
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, "Property: DAQmx_DigEdge_StartTrig_Edge\n"
                         f"Requested Value: {edge}\nPossible Values: Rising ({RISING}), "
                         f"Falling ({FALLING})")
    return edge


def check_type(kind: int) -> int:
    if kind not in (DIGITAL_EDGE, NO_TRIGGER):
        name = TriggerType(kind).name if kind in {t.value for t in TriggerType} else kind
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_StartTrig_Type\nRequested "
                         f"Value: {name}\nPossible Values: Digital Edge ({DIGITAL_EDGE}), "
                         f"None ({NO_TRIGGER})")
    return kind


def refuse_analog(rpc: str) -> DaqmxError:
    """An analog start trigger: the USB-6001 has only digital triggers."""
    kind = "Analog Window" if "Window" in rpc else (
        "Analog Multi Edge" if "Multi" in rpc else "Analog Edge")
    return DaqmxError(INVALID_ATTRIBUTE_VALUE,
                      f"DAQmx{rpc}\nProperty: DAQmx_StartTrig_Type\nRequested Value: {kind}\n"
                      f"Possible Values: Digital Edge ({DIGITAL_EDGE}), None ({NO_TRIGGER})")


def refuse_reference(rpc: str) -> DaqmxError:
    """A reference trigger: the USB-6001 has none."""
    kind = "Analog Edge" if "Anlg" in rpc else "Digital Edge" if "Dig" in rpc else rpc
    return DaqmxError(INVALID_ATTRIBUTE_VALUE,
                      f"DAQmx{rpc}\nProperty: DAQmx_RefTrig_Type\nRequested Value: {kind}\n"
                      f"Possible Values: None ({NO_TRIGGER})")


def refuse_retrigger() -> DaqmxError:
    return DaqmxError(ATTRIBUTE_NOT_SUPPORTED_IN_TASK_CONTEXT,
                      "Property: DAQmx_StartTrig_Retriggerable\nThe USB-6001 cannot retrigger.")
