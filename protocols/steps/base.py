"""What every step kind provides: its parameters, its columns, its plan and how it runs."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from instrument.fields import Field, parse_table
from protocols.context import StepContext

Params = dict[str, Any]


@dataclass
class PlanCheck:
    """A limit check made before anything moves."""

    name: str
    ok: bool
    message: str


@dataclass
class StepPlan:
    """A step summarised before it runs: lab duration (s), travel (m), what it does."""

    duration: float
    travel: float
    lines: list[str] = field(default_factory=list)
    checks: list[PlanCheck] = field(default_factory=list)


class StepDefinition:
    """Base of the step kinds. Subclasses set the class attributes and implement plan/run."""

    kind: ClassVar[str] = ""
    rig: ClassVar[str] = ""
    description: ClassVar[str] = ""
    fields: ClassVar[tuple[Field, ...]] = ()
    columns: ClassVar[dict[str, str]] = {}

    def parse(self, table: Mapping[str, Any], prefix: str, source: str | None) -> Params:
        """Validated SI parameters from a protocol-file table (``kind``/``name`` excluded)."""
        return dict(parse_table(table, self.fields, prefix, source, ignore=("kind", "name")))

    def plan(self, params: Params, limits: Any) -> StepPlan:
        raise NotImplementedError

    def run(self, ctx: StepContext, params: Params) -> dict[str, Any]:
        raise NotImplementedError
