"""The step kinds a protocol file can name, each in its own module."""

from __future__ import annotations

from typing import Any

from protocols.steps.base import StepDefinition, StepParams, StepResult
from protocols.steps.compression_search import CompressionContactSearch
from protocols.steps.ladder import SpeedLadder
from protocols.steps.ramp_hold import RampHold
from protocols.steps.shear_search import ShearContactSearch

#: kind -> definition, for protocol files
KINDS: dict[str, StepDefinition[Any, Any, Any]] = {
    d.kind: d
    for d in (CompressionContactSearch(), RampHold(), ShearContactSearch(), SpeedLadder())
}

__all__ = ["KINDS", "StepDefinition", "StepParams", "StepResult"]
