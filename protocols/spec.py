"""Protocol files (TOML): a name, the rig they run on, and a list of steps with parameters.

Loading validates everything before anything moves; errors name the file, the field (as
``step[2].speed``), the value and what is allowed::

    [protocol]
    name = "Paper compression"
    rig = "compression"          # or "shear"

    [[step]]
    kind = "compression_contact_search"
    name = "find the sphere"
    speed = "0.3 mm/s"
    ...
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from instrument.errors import ConfigError
from instrument.fields import Where, read_toml
from protocols.steps import KINDS, StepDefinition, load_step_modules
from protocols.steps.base import StepParams, StepResult

RIGS = ("compression", "shear")
#: Longest step name: names become file names (``steps/NN_name.h5``).
MAX_STEP_NAME = 80


@dataclass(frozen=True)
class Step:
    """One step of a protocol: its kind, a name, validated SI parameters."""

    definition: StepDefinition[Any, Any, Any]
    name: str
    params: StepParams

    @property
    def kind(self) -> str:
        return self.definition.kind


class StepSink(Protocol):
    """Where a procedure sends its steps (the runner): runs one, returns its typed result; a
    step a resumed run completed before is not run again, its stored result comes back."""

    def step(self, step: Step) -> StepResult: ...

    def checkpoint(self) -> None: ...


@dataclass(frozen=True)
class ProtocolSpec:
    """A validated protocol; ``table`` is the file's content, stored beside the data."""

    name: str
    rig: str
    steps: tuple[Step, ...]
    table: dict[str, Any]
    source: str = "<protocol>"

    def drive(self, sink: StepSink) -> None:
        """Send each step to ``sink`` in the file's order (a :class:`Procedure`)."""
        for step in self.steps:
            sink.step(step)


def parse_protocol(table: dict[str, Any], source: str = "<protocol>") -> ProtocolSpec:
    """Validate a protocol given as a TOML table."""
    head = table.get("protocol")
    if not isinstance(head, dict):
        raise ConfigError("[protocol]", "missing", "a [protocol] table with name and rig", source)
    unknown = set(table) - {"protocol", "step"}
    if unknown:
        key = sorted(unknown)[0]
        raise ConfigError(key, "?", "unknown table; allowed: [protocol], [[step]]", source)
    name = head.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ConfigError("[protocol] name", name, "a non-empty string", source)
    rig = head.get("rig")
    if rig not in RIGS:
        raise ConfigError("[protocol] rig", rig, f"allowed: {', '.join(RIGS)}", source)
    extra = set(head) - {"name", "rig", "description", "step_kinds"}
    if extra:
        key = sorted(extra)[0]
        raise ConfigError(f"[protocol] {key}", head[key],
                          "unknown field; allowed: name, rig, description, step_kinds", source)
    modules = head.get("step_kinds", [])
    if not isinstance(modules, list):
        raise ConfigError("[protocol] step_kinds", modules, "a list of .py files next to the "
                          "protocol file, or module names", source)
    load_step_modules(modules, Path(source).parent, source)
    raw_steps = table.get("step")
    if not isinstance(raw_steps, list) or not raw_steps:
        raise ConfigError("[[step]]", "missing", "at least one [[step]] table", source)
    steps = []
    for i, raw in enumerate(raw_steps):
        where = Where(f"step[{i}]", source)
        if not isinstance(raw, dict):
            raise where.error("", raw, "a [[step]] table")
        kind = raw.get("kind")
        steps.append(make_step(kind, raw.get("name"), raw, rig, where))
    return ProtocolSpec(name, rig, tuple(steps), table, source)


def make_step(kind: object, name: object, params: Mapping[str, Any], rig: str,
              where: Where) -> Step:
    """One validated step: ``kind`` (a registered kind's name, or a step definition),
    ``name`` (default: the kind's description), ``params`` as a protocol file's table holds
    them (unit strings or SI numbers; ``kind`` and ``name`` keys are ignored)."""
    if isinstance(kind, type) and issubclass(kind, StepDefinition):
        definition: StepDefinition[Any, Any, Any] | None = KINDS.get(kind.kind)
        if definition is None or type(definition) is not kind:
            definition = kind()
    elif isinstance(kind, StepDefinition):
        definition = kind
    else:
        definition = KINDS.get(kind) if isinstance(kind, str) else None
    if definition is None:
        allowed = ", ".join(k for k, d in KINDS.items() if d.rig_kind == rig)
        raise where.error("kind", kind, f"allowed for a {rig} rig: {allowed}")
    if definition.rig_kind != rig:
        raise where.error("kind", definition.kind,
                          f"runs on the {definition.rig_kind} rig, not the {rig} rig")
    step_name = definition.description or definition.kind if name is None else name
    if not isinstance(step_name, str) or not step_name.strip():
        raise where.error("name", step_name, "a non-empty string")
    if len(step_name) > MAX_STEP_NAME or not step_name.isprintable():
        shown = step_name if len(step_name) <= 40 else f"{step_name[:37]}..."
        raise where.error("name", shown.encode("unicode_escape").decode(),
                          f"printable, at most {MAX_STEP_NAME} characters (the step's data "
                          "file is named after it)")
    return Step(definition, step_name, definition.parse(params, where))


def load_protocol(path: str | Path) -> ProtocolSpec:
    """Read and validate a protocol file."""
    return parse_protocol(read_toml(path, "protocol file"), str(path))


def paper_protocol(name: str) -> Path:
    """Path of a shipped paper protocol: 'compression' or 'shear'."""
    path = Path(__file__).parent / "paper" / f"{name}.toml"
    if not path.exists():
        raise ConfigError("protocol", name, "allowed: compression, shear")
    return path
