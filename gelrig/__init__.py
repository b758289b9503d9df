"""gelrig's public scripting API, and the composition roots (the console entry point, the rig
factory).

Everything a script needs is importable from here; the names in ``__all__`` are the stable
surface (docs/scripting.md walks through them), each with its docstring. They are imported on
first use, so ``import gelrig`` (and ``gelrig --help``) stays fast. Nothing inside gelrig's
own packages imports this package.

- run things: :func:`open_rig`, :class:`RigSession`, :class:`RunResult`,
  :class:`InteractiveRun`, :func:`rehearse`, :func:`analyze`, :func:`load_protocol`,
  :func:`script_main`
- find and read runs: :func:`runs`, :func:`load_run`, :class:`LoadedRun`, :class:`LoadedStep`
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
  :class:`WaitResult`, :class:`MoveResult`, :class:`RestResult`, :class:`LoadUnloadResult`,
  :class:`CreepResult`, :class:`ShearSearchResult`, :class:`ShearWaitResult`,
  :class:`LadderResult`
- events: :class:`Event`, :class:`StepStarted`, :class:`Samples`, :class:`Progress`,
  :class:`FitUpdate`, :class:`Note`, :class:`StepFinished`, :class:`Finished`,
  :class:`RunState`
- clocks: :class:`VirtualClock`, :class:`RealClock`, :class:`PacedClock`
- errors: :class:`GelrigError`, :class:`ConfigError`, :class:`LimitError`, :class:`Refused`,
  :class:`InterlockTripped`, :class:`InstrumentError`, :class:`NotHomed`, :class:`RunEnded`,
  :class:`FirstTouchUnknown`
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: public name -> module it lives in
_SURFACE: dict[str, str] = {
    "open_rig": "gelrig.api", "RigSession": "gelrig.api", "RunResult": "gelrig.api",
    "rehearse": "gelrig.api", "analyze": "gelrig.api", "script_main": "gelrig.api",
    "InteractiveRun": "gelrig.interactive",
    "load_protocol": "gelrig.api",
    "runs": "gelrig.catalog", "load_run": "gelrig.catalog", "LoadedRun": "gelrig.catalog",
    "LoadedStep": "gelrig.catalog",
    "protocol": "gelrig.protocols.script", "Run": "gelrig.protocols.script",
    "Script": "gelrig.protocols.script", "Sample": "gelrig.protocols.sample",
    "register_step": "gelrig.api", "step_kinds": "gelrig.api",
    "StepDefinition": "gelrig.protocols.steps.base", "StepParams": "gelrig.protocols.steps.base",
    "StepResult": "gelrig.protocols.steps.base", "StepPlan": "gelrig.protocols.steps.base",
    "PlanCheck": "gelrig.protocols.steps.base", "StepContext": "gelrig.protocols.context",
    "Field": "gelrig.instrument.core.fields", "FieldList": "gelrig.instrument.core.fields",
    "Choice": "gelrig.instrument.core.fields", "param": "gelrig.instrument.core.fields",
    "Where": "gelrig.instrument.core.fields",
    "stage_speed_error": "gelrig.protocols.caps", "stage_position_error": "gelrig.protocols.caps",
    "arm_speed_error": "gelrig.protocols.caps", "gap_error": "gelrig.protocols.caps",
    "ForceRecorder": "gelrig.protocols.steps.acquire", "ArmRecorder": "gelrig.protocols.steps.arm",
    "CompressionRig": "gelrig.protocols.rig", "ShearRig": "gelrig.protocols.rig",
    "CompressionLimits": "gelrig.protocols.rig", "ShearLimits": "gelrig.protocols.rig",
    "Stage": "gelrig.instrument.contracts.stage",
    "ForceSensor": "gelrig.instrument.contracts.loadcell",
    "Rheometer": "gelrig.instrument.contracts.rheometer",
    "SearchResult": "gelrig.protocols.steps.compression_search",
    "RampHoldResult": "gelrig.protocols.steps.ramp_hold",
    "ShearSearchResult": "gelrig.protocols.steps.shear_search",
    "LadderResult": "gelrig.protocols.steps.ladder",
    "WaitResult": "gelrig.protocols.steps.wait", "MoveResult": "gelrig.protocols.steps.move",
    "RestResult": "gelrig.protocols.steps.rest",
    "LoadUnloadResult": "gelrig.protocols.steps.load_unload",
    "CreepResult": "gelrig.protocols.steps.creep",
    "ShearWaitResult": "gelrig.protocols.steps.shear_wait",
    "Event": "gelrig.protocols.events", "StepStarted": "gelrig.protocols.events",
    "Samples": "gelrig.protocols.events", "Progress": "gelrig.protocols.events",
    "FitUpdate": "gelrig.protocols.events", "StepFinished": "gelrig.protocols.events",
    "Note": "gelrig.protocols.events",
    "Finished": "gelrig.protocols.events", "RunState": "gelrig.protocols.events",
    "VirtualClock": "gelrig.instrument.core.clock", "RealClock": "gelrig.instrument.core.clock",
    "PacedClock": "gelrig.instrument.core.clock",
    "GelrigError": "gelrig.instrument.core.errors", "ConfigError": "gelrig.instrument.core.errors",
    "LimitError": "gelrig.instrument.core.errors", "Refused": "gelrig.instrument.core.errors",
    "InterlockTripped": "gelrig.instrument.core.errors",
    "RunEnded": "gelrig.protocols.runner",
    "InstrumentError": "gelrig.instrument.core.errors", "NotHomed": "gelrig.protocols.rig",
    "FirstTouchUnknown": "gelrig.protocols.manual_motion",
}

__all__ = [
    "ArmRecorder", "Choice", "CompressionLimits", "CompressionRig", "ConfigError", "CreepResult",
    "Event", "Field", "FieldList", "Finished", "FirstTouchUnknown", "FitUpdate", "ForceRecorder",
    "ForceSensor", "GelrigError", "InstrumentError", "InteractiveRun", "InterlockTripped",
    "LadderResult", "LimitError", "LoadUnloadResult", "LoadedRun", "LoadedStep", "MoveResult",
    "NotHomed", "Note",
    "PacedClock", "PlanCheck", "Progress", "RampHoldResult", "RealClock", "Refused", "RestResult",
    "Rheometer", "RigSession", "Run", "RunEnded", "RunResult", "RunState", "Sample", "Samples",
    "Script", "SearchResult", "ShearLimits", "ShearRig", "ShearSearchResult", "ShearWaitResult",
    "Stage", "StepContext", "StepDefinition", "StepFinished", "StepParams", "StepPlan",
    "StepResult", "StepStarted", "VirtualClock", "WaitResult", "Where", "analyze",
    "arm_speed_error", "gap_error", "load_protocol", "load_run", "open_rig", "param", "protocol",
    "register_step", "rehearse", "runs", "script_main", "stage_position_error", "stage_speed_error",
    "step_kinds",
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
    from gelrig.catalog import LoadedRun, LoadedStep, load_run, runs
    from gelrig.instrument.contracts.loadcell import ForceSensor
    from gelrig.instrument.contracts.rheometer import Rheometer
    from gelrig.instrument.contracts.stage import Stage
    from gelrig.instrument.core.clock import PacedClock, RealClock, VirtualClock
    from gelrig.instrument.core.errors import (
        ConfigError,
        GelrigError,
        InstrumentError,
        InterlockTripped,
        LimitError,
        Refused,
    )
    from gelrig.instrument.core.fields import Choice, Field, FieldList, Where, param
    from gelrig.interactive import InteractiveRun
    from gelrig.protocols.caps import (
        arm_speed_error,
        gap_error,
        stage_position_error,
        stage_speed_error,
    )
    from gelrig.protocols.context import StepContext
    from gelrig.protocols.events import (
        Event,
        Finished,
        FitUpdate,
        Note,
        Progress,
        RunState,
        Samples,
        StepFinished,
        StepStarted,
    )
    from gelrig.protocols.manual_motion import FirstTouchUnknown
    from gelrig.protocols.rig import (
        CompressionLimits,
        CompressionRig,
        NotHomed,
        ShearLimits,
        ShearRig,
    )
    from gelrig.protocols.runner import RunEnded
    from gelrig.protocols.sample import Sample
    from gelrig.protocols.script import Run, Script, protocol
    from gelrig.protocols.steps.acquire import ForceRecorder
    from gelrig.protocols.steps.arm import ArmRecorder
    from gelrig.protocols.steps.base import (
        PlanCheck,
        StepDefinition,
        StepParams,
        StepPlan,
        StepResult,
    )
    from gelrig.protocols.steps.compression_search import SearchResult
    from gelrig.protocols.steps.creep import CreepResult
    from gelrig.protocols.steps.ladder import LadderResult
    from gelrig.protocols.steps.load_unload import LoadUnloadResult
    from gelrig.protocols.steps.move import MoveResult
    from gelrig.protocols.steps.ramp_hold import RampHoldResult
    from gelrig.protocols.steps.rest import RestResult
    from gelrig.protocols.steps.shear_search import ShearSearchResult
    from gelrig.protocols.steps.shear_wait import ShearWaitResult
    from gelrig.protocols.steps.wait import WaitResult


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
