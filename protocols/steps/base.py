"""What every step kind provides: typed parameters, a typed result, its columns, plan and run.

A step kind is a :class:`StepDefinition` generic over the rig it runs on, its parameters and
its result::

    @dataclass(frozen=True)
    class CreepParams(StepParams):
        force: float = param(Field("force", "N", 0.1, 0.0, 2.0, lo_open=True))
        hold: float = param(Field("hold", "s", 600.0, 0.0, 86400.0))

    @dataclass(frozen=True)
    class CreepResult(StepResult):
        final_position_m: float

    class Creep(StepDefinition[CompressionRig, CreepParams, CreepResult]):
        kind = "creep"
        rig = CompressionRig
        Params, Result = CreepParams, CreepResult
        def plan(self, params, limits): ...
        def run(self, ctx, params): ...

Parameters are read from a protocol file's ``[[step]]`` table by the one configuration reader
(:mod:`gelrig.instrument.core.fields`), so they carry units, defaults, ranges and help once. A
result is
stored in run.json as a table (:meth:`StepResult.as_dict`) and read back typed on resume; a
later step asks for an earlier one by type (:meth:`StepContext.earlier`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Generic, Self, TypeVar

from gelrig.instrument.core.fields import Config, Field, Where
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import CompressionLimits, CompressionRig, ShearLimits, ShearRig


@dataclass(frozen=True)
class StepParams(Config):
    """Base of step parameters: a validated config read from one ``[[step]]`` table."""

    section: ClassVar[str] = "step"


@dataclass(frozen=True, repr=False)
class StepResult:
    """Base of step results: stored in run.json as a table, read back typed on resume. Its
    ``repr`` is one line (numbers short, lists and tables counted, not dumped); a subclass
    keeps it with ``@dataclass(frozen=True, repr=False)``, or writes its own."""

    def __repr__(self) -> str:
        parts = []
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, list | tuple | dict):
                parts.append(f"{f.name} [{len(value)}]")
            elif isinstance(value, float):
                parts.append(f"{f.name} {value:.4g}")
            else:
                text = repr(value)
                parts.append(f"{f.name} {text if len(text) <= 40 else text[:37] + '...'}")
        return brief(type(self).__name__, *parts)

    def as_dict(self) -> dict[str, Any]:
        """The result as run.json stores it (nested dataclasses become tables)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, table: Mapping[str, Any]) -> Self:
        """A stored result (run.json) as this type; missing optional fields take defaults."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in table.items() if k in names})


@dataclass
class PlanCheck:
    """A limit check made before anything moves."""

    name: str
    ok: bool
    message: str


@dataclass
class StepPlan:
    """A step summarised before it runs: lab duration (s), travel (m), what it does, and the
    samples (rows) it records at most (0: the step kind does not say; see protocols/bounds)."""

    duration: float
    travel: float
    lines: list[str] = field(default_factory=list)
    checks: list[PlanCheck] = field(default_factory=list)
    samples: float = 0.0


RigT = TypeVar("RigT", CompressionRig, ShearRig)
ParamsT = TypeVar("ParamsT", bound=StepParams)
ResultT = TypeVar("ResultT", bound=StepResult)
Limits = CompressionLimits | ShearLimits


class StepDefinition(Generic[RigT, ParamsT, ResultT]):
    """Base of the step kinds: set the class attributes, implement ``plan`` and ``run``.

    ``rig`` is the rig class the step runs on (the runner refuses any other); ``Params``
    and ``Result`` are the dataclasses of its parameters and its result; ``columns`` names
    the recorded columns with their units.
    """

    kind: ClassVar[str] = ""
    rig: ClassVar[type[CompressionRig] | type[ShearRig]]
    description: ClassVar[str] = ""
    columns: ClassVar[dict[str, str]] = {}
    Params: type[ParamsT]
    Result: type[ResultT]
    #: parameters that are sizes of the run's sample, by their key: the sample's field each
    #: takes (``{"diameter": "diameter"}``). A step given none of its own takes the sample's;
    #: one given neither is refused before anything moves (docs/decisions/0280)
    sample_fields: ClassVar[Mapping[str, str]] = {}

    @property
    def rig_kind(self) -> str:
        """``"compression"`` or ``"shear"``: what protocol files name."""
        return self.rig.kind

    @property
    def fields(self) -> tuple[Field, ...]:
        """The numeric fields of the parameters (forms build one entry each)."""
        return tuple(s for s in self.Params.specs().values() if isinstance(s, Field))

    def parse(self, table: Mapping[str, Any], where: Where) -> ParamsT:
        """Validated parameters from a protocol-file table (``kind``/``name`` excluded)."""
        return self.Params.from_table(table, where.source, where.section,
                                      ignore=("kind", "name"))

    def plan(self, params: ParamsT, limits: Limits) -> StepPlan:
        raise NotImplementedError

    def run(self, ctx: StepContext[RigT], params: ParamsT) -> ResultT:
        raise NotImplementedError

    def preflight(self, params: ParamsT, rig: RigT,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        """Why ``rig`` would refuse this step, known from its parameters before anything
        moves: commanded speeds, positions or overlaps beyond the rig's caps, or an earlier
        result it needs (``earlier``: the result types of the steps before it). [] if none."""
        return []


def brief(name: str, *parts: str) -> str:
    """A result's one-line repr: ``<Name part, part, ...>`` (empty parts left out)."""
    return f"<{name} {', '.join(p for p in parts if p)}>"


def mm(value: float | None, digits: int = 4) -> str:
    """A length in m as people read it: ``6.2003 mm`` (``? mm`` when unknown)."""
    if value is None or not math.isfinite(value):
        return "? mm"
    return f"{value * 1e3:.{digits}f} mm"


def given(value: float | None) -> float | None:
    """``value`` if it is a finite number, else None (an optional parameter left out)."""
    return value if value is not None and math.isfinite(value) else None
