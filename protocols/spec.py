"""Protocol files (TOML): a name, the rig they run on, and a list of steps with parameters.

Loading validates everything before anything moves; errors name the file, the field (as
``step[2].speed``), the value and what is allowed::

    [protocol]
    name = "Paper compression"
    rig = "compression"          # or "shear"

    [sample]                     # the run's sample (docs/decisions/0280)
    name = "PDMS sphere A3"
    diameter = "12 mm"

    [[step]]
    kind = "compression_contact_search"
    name = "find the sphere"
    speed = "0.3 mm/s"

    [[step]]                     # repeat: the same step 3 times, "cycle 1" .. "cycle 3"
    kind = "load_unload"
    name = "cycle"
    repeat = 3
    ...
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn, Protocol

from gelrig.instrument.core.errors import ConfigError, shown
from gelrig.instrument.core.fields import FieldList, Where, read_toml, written_unit
from gelrig.protocols.bounds import MAX_STEPS
from gelrig.protocols.sample import HOW_TO_GIVE, Sample, SampleSizeMissing, parse_sample
from gelrig.protocols.steps import KINDS, StepDefinition, load_step_modules
from gelrig.protocols.steps.base import StepParams, StepResult

RIGS = ("compression", "shear")
#: Longest step name: names become file names (``steps/NN_name.h5``).
MAX_STEP_NAME = 80


@dataclass(frozen=True)
class Step:
    """One step of a protocol: its kind, a name, validated SI parameters."""

    definition: StepDefinition[Any, Any, Any]
    name: str
    params: StepParams
    #: the parameters as written (unit strings kept): what ``gelrig plan`` shows each
    #: effective value in
    given: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    #: the keys whose values came from the run's sample
    sampled: tuple[str, ...] = ()

    @property
    def kind(self) -> str:
        return self.definition.kind


class StepSink(Protocol):
    """Where a procedure sends its steps (the runner): runs one, returns its typed result; a
    step a resumed run completed before is not run again, its stored result comes back."""

    def step(self, step: Step) -> StepResult: ...

    def checkpoint(self) -> None: ...

    def note(self, text: str) -> None:
        """A line for people: the run's log, and the console when one shows the run."""
        ...

    def refuse(self, name: str, problem: str) -> NoReturn:
        """End the run: the next step (``name``) is not valid and is refused before it
        moves (``problem``: the one line saying why)."""
        ...


@dataclass(frozen=True)
class ProtocolSpec:
    """A validated protocol; ``table`` is the file's content, stored beside the data."""

    name: str
    rig: str
    steps: tuple[Step, ...]
    table: dict[str, Any]
    source: str = "<protocol>"
    #: the run's sample (the file's ``[sample]`` table), None when the file states none
    sample: Sample | None = None

    def with_sample(self, sample: Sample) -> ProtocolSpec:
        """This protocol measuring ``sample`` instead of the file's: read again, so every
        step that takes a size from the sample takes this one."""
        return parse_protocol({**self.table, "sample": sample.table()}, self.source)

    def drive(self, sink: StepSink) -> None:
        """Send each step to ``sink`` in the file's order (a :class:`Procedure`)."""
        for step in self.steps:
            sink.step(step)


def parse_protocol(table: dict[str, Any], source: str = "<protocol>") -> ProtocolSpec:
    """Validate a protocol given as a TOML table."""
    head = table.get("protocol")
    if not isinstance(head, dict):
        raise ConfigError("[protocol]", "missing", "a [protocol] table with name and rig", source)
    unknown = set(table) - {"protocol", "sample", "step"}
    if unknown:
        key = sorted(unknown)[0]
        raise ConfigError(key, "?", "unknown table; allowed: [protocol], [sample], [[step]]",
                          source)
    sample = parse_sample(table["sample"], source) if "sample" in table else None
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
    if len(raw_steps) > MAX_STEPS:  # before reading any: a rehearsal takes ~0.5 s a step
        raise ConfigError("[[step]]", f"{len(raw_steps):,} tables", f"at most {MAX_STEPS} "
                          "steps per protocol; split it into several protocols", source)
    steps: list[Step] = []
    for i, raw in enumerate(raw_steps):
        where = Where(f"step[{i}]", source)
        if not isinstance(raw, dict):
            raise where.error("", raw, "a [[step]] table")
        steps += table_steps(raw, rig, where, sample)
        if len(steps) > MAX_STEPS:
            raise where.error("repeat", raw.get("repeat"), f"the protocol would have "
                              f"{len(steps):,} steps; at most {MAX_STEPS} per protocol")
    return ProtocolSpec(name, rig, tuple(steps), table, source, sample)


def table_steps(raw: Mapping[str, Any], rig: str, where: Where,
                sample: Sample | None = None) -> list[Step]:
    """The steps of one ``[[step]]`` table: one, or with ``repeat = N`` the same step N
    times, named ``NAME 1`` .. ``NAME N`` (a user-defined sequence in a protocol file)."""
    repeat = raw.get("repeat")
    body = {k: v for k, v in raw.items() if k != "repeat"}
    first = make_step(body.get("kind"), body.get("name"), body, rig, where, sample)
    if repeat is None:
        return [first]
    if isinstance(repeat, bool) or not isinstance(repeat, int) or not 1 <= repeat <= MAX_STEPS:
        raise where.error("repeat", repeat, f"an integer in [1, {MAX_STEPS}]: the step is "
                          "run that many times")
    return [make_step(body.get("kind"), f"{first.name} {n}", body, rig, where, sample)
            for n in range(1, repeat + 1)]


def make_step(kind: object, name: object, params: Mapping[str, Any], rig: str,
              where: Where, sample: Sample | None = None) -> Step:
    """One validated step: ``kind`` (a registered kind's name, or a step definition),
    ``name`` (default: the kind's description), ``params`` as a protocol file's table holds
    them (unit strings or SI numbers; ``kind`` and ``name`` keys are ignored). A size the
    step takes from the run's ``sample`` (``diameter``) is filled in from it; one neither
    given nor in the sample is a ConfigError naming the field (never a paper value)."""
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
    filled = with_sample_sizes(definition, params, sample, where)
    return Step(definition, step_name, definition.parse(filled, where), dict(params),
                tuple(k for k in filled if k not in params))


def with_sample_sizes(definition: StepDefinition[Any, Any, Any], params: Mapping[str, Any],
                      sample: Sample | None, where: Where) -> Mapping[str, Any]:
    """``params`` with each size the step takes from the sample filled in; a size the step
    states itself must equal the sample's (one sphere per run)."""
    if not definition.sample_fields:
        return params
    specs = {spec.key: spec for spec in definition.Params.specs().values()}
    out = dict(params)
    for key, attr in definition.sample_fields.items():
        size = sample.size(attr) if sample is not None else None
        if params.get(key) is not None:
            given = specs[key].parse(params[key], where)
            if size is not None and not math.isclose(float(given), size, rel_tol=1e-9):
                raise where.error(key, params[key], f"differs from the sample's {attr} "
                                  f"({size * 1e3:g} mm); state the size once, in the sample")
            continue
        if size is None:
            raise SampleSizeMissing(where.name(key), f"the sample's {attr} is needed and "
                                    f"none was given; give {HOW_TO_GIVE.format(key=attr)} (or "
                                    f"{key} in the step)", where.source, attr)
        out[key] = size
    return out


def effective_params(step: Step) -> list[str]:
    """Every parameter ``step`` runs with, defaults included, as people read it: in the unit
    it was written in (``speed = 0.3 mm/s``), else the field's display unit; a value not
    given is marked ``(default)``, one taken from the run's sample ``(sample)``."""
    given = step.given
    out = []
    for name, spec in step.params.specs().items():
        key = spec.key
        value = getattr(step.params, name)
        raw = given.get(key)
        written = key in given
        unit = getattr(spec, "unit", "")
        if isinstance(spec, FieldList):
            unit = spec.item.unit
            first = raw[0] if written and isinstance(raw, list | tuple) and raw else None
            show = written_unit(first) or spec.item.display or unit
        else:
            show = (written_unit(raw) if written else None) or getattr(spec, "display", "") \
                or unit
        if value is None:
            text = "none"
        elif isinstance(value, bool | str):
            text = shown(value)
        elif isinstance(value, tuple):
            text = "[" + ", ".join(_number(v, unit, show) for v in value) + "]"
        else:
            text = _number(float(value), unit, show)
        mark = "" if written else " (sample)" if key in step.sampled else " (default)"
        out.append(f"{key} = {text}{mark}")
    return out


def _number(value: float, unit: str, show: str) -> str:
    from gelrig.instrument.core.units import convert

    if show and unit and show != unit:
        try:
            return f"{convert(value, unit, show):.6g} {show}"
        except ConfigError:
            pass
    return f"{value:.6g} {unit}".rstrip()


def load_protocol(path: str | Path) -> ProtocolSpec:
    """Read and validate a protocol file."""
    return parse_protocol(read_toml(path, "protocol file"), str(path))


def paper_protocol(name: str) -> Path:
    """Path of a shipped paper protocol: 'compression' or 'shear'."""
    path = Path(__file__).parent / "paper" / f"{name}.toml"
    if not path.exists():
        raise ConfigError("protocol", name, "allowed: compression, shear")
    return path
