"""gelrig's public scripting API, and the composition roots (the console entry point, the rig
factory).

Everything a script needs is importable from here; the names in ``__all__`` are the stable
surface (docs/scripting.md walks through them), each with its docstring. They are imported on
first use, so ``import gelrig`` (and ``gelrig --help``) stays fast. Nothing inside gelrig's
own packages imports this package.

- run things: :func:`open_rig`, :class:`RigSession`, :class:`RunResult`, :func:`rehearse`,
  :func:`analyze`, :func:`load_protocol`, :func:`script_main`
- write scripts: :func:`protocol`, :class:`Run`, :class:`Script`
- write step kinds: :func:`register_step`, :class:`StepDefinition`, :class:`StepParams`,
  :class:`StepResult`, :class:`StepPlan`, :class:`PlanCheck`, :class:`StepContext`,
  :class:`Field`, :class:`FieldList`, :class:`Choice`, :func:`param`, :class:`Where`,
  :class:`ForceRecorder`, :class:`ArmRecorder`, :func:`step_kinds`, and the caps' checks
  :func:`stage_speed_error`, :func:`stage_position_error`, :func:`arm_speed_error`,
  :func:`gap_error` (for a step's ``preflight``)
- the rigs and instrument contracts: :class:`CompressionRig`, :class:`ShearRig`,
  :class:`CompressionLimits`, :class:`ShearLimits`, :class:`Stage`, :class:`ForceSensor`,
  :class:`Rheometer`
- results of the built-in steps: :class:`SearchResult`, :class:`RampHoldResult`,
  :class:`ShearSearchResult`, :class:`LadderResult`
- events: :class:`Event`, :class:`StepStarted`, :class:`Samples`, :class:`Progress`,
  :class:`FitUpdate`, :class:`StepFinished`, :class:`Finished`, :class:`RunState`
- clocks: :class:`VirtualClock`, :class:`RealClock`, :class:`PacedClock`
- errors: :class:`GelrigError`, :class:`ConfigError`, :class:`LimitError`,
  :class:`InterlockTripped`, :class:`InstrumentError`, :class:`NotHomed`, :class:`RunEnded`
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: public name -> module it lives in
_SURFACE: dict[str, str] = {
    "open_rig": "gelrig.api", "RigSession": "gelrig.api", "RunResult": "gelrig.api",
    "rehearse": "gelrig.api", "analyze": "gelrig.api", "script_main": "gelrig.api",
    "load_protocol": "gelrig.api",
    "protocol": "protocols.script", "Run": "protocols.script", "Script": "protocols.script",
    "register_step": "gelrig.api", "step_kinds": "gelrig.api",
    "StepDefinition": "protocols.steps.base", "StepParams": "protocols.steps.base",
    "StepResult": "protocols.steps.base", "StepPlan": "protocols.steps.base",
    "PlanCheck": "protocols.steps.base", "StepContext": "protocols.context",
    "Field": "instrument.fields", "FieldList": "instrument.fields",
    "Choice": "instrument.fields", "param": "instrument.fields", "Where": "instrument.fields",
    "stage_speed_error": "protocols.caps", "stage_position_error": "protocols.caps",
    "arm_speed_error": "protocols.caps", "gap_error": "protocols.caps",
    "ForceRecorder": "protocols.steps.acquire", "ArmRecorder": "protocols.steps.arm",
    "CompressionRig": "protocols.rig", "ShearRig": "protocols.rig",
    "CompressionLimits": "protocols.rig", "ShearLimits": "protocols.rig",
    "Stage": "instrument.stage", "ForceSensor": "instrument.loadcell",
    "Rheometer": "instrument.rheometer",
    "SearchResult": "protocols.steps.compression_search",
    "RampHoldResult": "protocols.steps.ramp_hold",
    "ShearSearchResult": "protocols.steps.shear_search",
    "LadderResult": "protocols.steps.ladder",
    "Event": "protocols.events", "StepStarted": "protocols.events",
    "Samples": "protocols.events", "Progress": "protocols.events",
    "FitUpdate": "protocols.events", "StepFinished": "protocols.events",
    "Finished": "protocols.events", "RunState": "protocols.events",
    "VirtualClock": "instrument.clock", "RealClock": "instrument.clock",
    "PacedClock": "instrument.clock",
    "GelrigError": "instrument.errors", "ConfigError": "instrument.errors",
    "LimitError": "instrument.errors", "InterlockTripped": "instrument.errors",
    "RunEnded": "protocols.runner",
    "InstrumentError": "instrument.errors", "NotHomed": "protocols.rig",
}

__all__ = [
    "ArmRecorder", "Choice", "CompressionLimits", "CompressionRig", "ConfigError", "Event",
    "Field", "FieldList", "Finished", "FitUpdate", "ForceRecorder", "ForceSensor",
    "GelrigError", "InstrumentError", "InterlockTripped", "LadderResult", "LimitError",
    "NotHomed", "PacedClock", "PlanCheck", "Progress", "RampHoldResult", "RealClock",
    "Rheometer", "RigSession", "Run", "RunEnded", "RunResult", "RunState", "Samples", "Script",
    "SearchResult", "ShearLimits", "ShearRig", "ShearSearchResult", "Stage", "StepContext",
    "StepDefinition", "StepFinished", "StepParams", "StepPlan", "StepResult", "StepStarted",
    "VirtualClock", "Where", "analyze", "arm_speed_error", "gap_error", "load_protocol",
    "open_rig", "param", "protocol", "register_step", "rehearse", "script_main",
    "stage_position_error", "stage_speed_error", "step_kinds",
]

if TYPE_CHECKING:
    from gelrig.api import (
        RigSession,
        RunResult,
        analyze,
        load_protocol,
        open_rig,
        register_step,
        rehearse,
        script_main,
        step_kinds,
    )
    from instrument.clock import PacedClock, RealClock, VirtualClock
    from instrument.errors import (
        ConfigError,
        GelrigError,
        InstrumentError,
        InterlockTripped,
        LimitError,
    )
    from instrument.fields import Choice, Field, FieldList, Where, param
    from instrument.loadcell import ForceSensor
    from instrument.rheometer import Rheometer
    from instrument.stage import Stage
    from protocols.caps import (
        arm_speed_error,
        gap_error,
        stage_position_error,
        stage_speed_error,
    )
    from protocols.context import StepContext
    from protocols.events import (
        Event,
        Finished,
        FitUpdate,
        Progress,
        RunState,
        Samples,
        StepFinished,
        StepStarted,
    )
    from protocols.rig import CompressionLimits, CompressionRig, NotHomed, ShearLimits, ShearRig
    from protocols.runner import RunEnded
    from protocols.script import Run, Script, protocol
    from protocols.steps.acquire import ForceRecorder
    from protocols.steps.arm import ArmRecorder
    from protocols.steps.base import PlanCheck, StepDefinition, StepParams, StepPlan, StepResult
    from protocols.steps.compression_search import SearchResult
    from protocols.steps.ladder import LadderResult
    from protocols.steps.ramp_hold import RampHoldResult
    from protocols.steps.shear_search import ShearSearchResult


def __getattr__(name: str) -> Any:
    """The public names, imported on first use; ``__version__`` from the installed
    distribution (importlib.metadata is slow to import)."""
    module = _SURFACE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
        globals()[name] = value
        return value
    if name != "__version__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("gelrig")
    except PackageNotFoundError:  # running from a source tree that is not installed
        found = "0+unknown"
    globals()["__version__"] = found
    return found


def __dir__() -> list[str]:
    return [*__all__, "__version__"]
