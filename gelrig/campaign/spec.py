"""The campaign file (TOML): a protocol, a rig twin, grids of hidden truth and of protocol
parameters, and a number of seeded replicates; expanded into members.

Every value is checked on load by the parsers of the rig and protocol files (one configuration
mechanism, ``gelrig.instrument.core.fields``), so an error names the campaign file, the table and
field,
the value as written and what is allowed::

    [campaign]
    name = "Paper ladder, 50 noise seeds"
    protocol = "paper:shear"          # a protocol file or script (relative to this file),
                                      # or paper:...
    rig = "my-rig.toml"               # optional; default the built-in rig of the protocol's kind
    replicates = 50                   # noise seeds first_seed .. first_seed + replicates - 1
    first_seed = 1

    [analysis]                        # optional: how each member is analysed
    terms = 1                         # relaxation terms of the shear model fit
    unloading = "cutoff"              # model fitted: "cutoff", "mdr" or "truth" (the member's)
    model_fit = true                  # false: l_c, l_g and mu per pass only (no ladder fit)

    [simulator]                       # the rig file's [simulator] keys; a list is a grid
    mu = [2e-3, 5e-3]
    relax = [[["20 kPa", "2000 s"]], [["10 kPa", "2000 s"]]]

    [params]                          # "step[i].field" or "<step name>.field"; a list is a grid
    "step[1].hold" = ["300 s", "3000 s"]

A list-valued field (``relax``, ``speeds``) takes a list of such lists as its grid. A
``[simulator]`` value (or any number inside one, such as a relaxation term's G) may instead be
a distribution, drawn anew for each member from its seed: ``{ uniform = ["4 kPa", "9 kPa"] }``,
``{ loguniform = [1e-3, 1e-2] }`` or ``{ normal = ["5e-3", "1e-3"] }`` (mean, standard
deviation), both ends in the same unit. A script's
``[params]`` are its function's keyword parameters by name (``hold = ["300 s", "3000 s"]``):
its steps are known only as it runs. The script is loaded by path on each worker (a remote
cluster's workers need it at the same path).
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
import re
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from gelrig.instrument.analysis.fit_setup import ANISOTROPIC, FIT_GEOMETRY, TERMS
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import (
    Config,
    Field,
    FieldList,
    Flag,
    Spec,
    Where,
    param,
    read_table,
    read_toml,
)
from gelrig.instrument.physics.truth import UNLOADING

#: Nesting depth of one value of these list-valued [simulator] keys (a list of [G, tau]).
_SIM_DEPTH = {"relax": 2, "relax_vertical": 2}
_SIM_RESERVED = ("seed",)
_HEAD: dict[str, Spec] = {
    "replicates": Field("replicates", "", 1, 1, 100_000, integer=True),
    "first_seed": Field("first_seed", "", 1, 0, 2**31 - 100_001, integer=True),
}
#: Most members a campaign expands to: 100,000 members take about 20 s and 440 MB to expand
#: (the paper's compression protocol), and as many seeds as ``replicates`` allows.
MAX_MEMBERS = 100_000
#: Protocol references that name a script (``gelrig.protocols.script``).
SCRIPT_SUFFIXES = (".py",)


@dataclass(frozen=True)
class Analysis(Config):
    """How each member's run is analysed (``gelrig analyze``'s options): the ``[analysis]``
    table, its fields the ladder fit's own declarations (``FitSetup``)."""

    section: ClassVar[str] = "analysis"
    exact_integers: ClassVar[bool] = True

    terms: int = param(TERMS)
    unloading: str = param(dataclasses.replace(
        UNLOADING, choices=(*UNLOADING.choices, "truth"),
        help="model fitted: the paper's cutoff, MDR, or the member's own (truth)"))
    anisotropic: bool = param(ANISOTROPIC)
    fit_geometry: bool = param(FIT_GEOMETRY)
    #: The ladder-wide model fit (shear); without it a member measures l_c, l_g and mu only.
    model_fit: bool = param(Flag("model_fit", True, help="the ladder-wide model fit (shear); "
                                 "false: l_c, l_g and mu per pass only"))


@dataclass(frozen=True)
class MemberSpec:
    """One member: what it runs, on which truth, with which protocol parameters and seed.

    ``truth`` and ``params`` hold the values as written (TOML values) for the keys varied or
    fixed by the campaign; ``rig_table`` and ``protocol_table`` are the full tables with them
    applied, ready for the rig and protocol parsers on a worker.
    """

    index: int
    member_id: str
    seed: int
    truth: dict[str, Any]
    params: dict[str, Any]
    rig_table: dict[str, Any]
    protocol_ref: str
    protocol_table: dict[str, Any] | None
    analysis: Analysis
    keep_dir: str | None = None
    #: ``gelrig campaign --sample/--operator/--note/--tag``: the sample's name and the
    #: run's operator, note and tags (ADR 0370), recorded in each member's run.json
    run_meta: dict[str, Any] | None = None


@dataclass(frozen=True)
class CampaignSpec:
    """A validated campaign file, with its members expanded."""

    name: str
    source: str
    protocol_ref: str
    rig_kind: str
    replicates: int
    first_seed: int
    analysis: Analysis
    truth_grid: dict[str, list[Any]]
    param_grid: dict[str, list[Any]]
    members: tuple[MemberSpec, ...] = field(default=())
    table: dict[str, Any] = field(default_factory=dict)


def _depth(value: object) -> int:
    """How deeply lists nest along the first elements of ``value``."""
    depth = 0
    while isinstance(value, list):
        if not value:
            return depth + 1
        depth, value = depth + 1, value[0]
    return depth


def _grid(key: str, raw: object, single_depth: int, where: Where) -> list[Any]:
    """The values of one grid axis: ``raw`` itself, or its items when it is a list of values."""
    depth = _depth(raw)
    if depth == single_depth:
        return [raw]
    if depth == single_depth + 1 and isinstance(raw, list):
        if not raw:
            raise where.error(key, raw, "a value or a non-empty list of values (a grid)")
        return list(raw)
    shape = {0: "a value", 1: "a list", 2: "a list of [G, tau] pairs"}.get(single_depth, "")
    raise where.error(key, raw, f"{shape} or a list of such values (a grid)")


#: Distributions a [simulator] value may be drawn from, with what their two numbers are.
DISTRIBUTIONS = {"uniform": "[low, high]", "loguniform": "[low, high], both > 0",
                 "normal": "[mean, standard deviation]"}
_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def _has_draw(value: object) -> bool:
    """Whether ``value`` is, or holds, a distribution table."""
    if isinstance(value, dict):
        return True
    return isinstance(value, list) and any(_has_draw(v) for v in value)


def _number(raw: object, key: str, where: Where) -> tuple[float, str]:
    """A distribution's number and the unit it was written in ('' for a bare number)."""
    if isinstance(raw, int | float) and not isinstance(raw, bool):
        return float(raw), ""
    match = _NUMBER.match(raw) if isinstance(raw, str) else None
    if match is None:
        raise where.error(key, raw, "a number, or a number with a unit (\"4 kPa\")")
    return float(match[1]), match[2]


def _check_draw(spec: dict[str, Any], key: str, where: Where) -> None:
    """One distribution table: its name, two numbers in one unit, a valid spread."""
    if len(spec) != 1 or next(iter(spec)) not in DISTRIBUTIONS:
        raise where.error(key, spec, "one of " + ", ".join(
            f"{{ {name} = {what} }}" for name, what in DISTRIBUTIONS.items()))
    (name, pair), = spec.items()
    if not isinstance(pair, list) or len(pair) != 2:
        raise where.error(key, pair, f"{name} takes two numbers: {DISTRIBUTIONS[name]}")
    (a, unit_a), (b, unit_b) = (_number(v, key, where) for v in pair)
    if unit_a != unit_b:
        raise where.error(key, pair, f"both numbers of {name} in one unit")
    ok = {"uniform": a < b, "loguniform": 0 < a < b, "normal": b > 0}[name]
    if not ok:
        raise where.error(key, pair, f"{name} takes {DISTRIBUTIONS[name]}"
                          + (" with low < high" if name != "normal" else ", sd > 0"))


def _draw(value: Any, rng: Any, key: str, where: Where) -> Any:
    """``value`` with every distribution table replaced by one draw (in the unit written)."""
    if isinstance(value, list):
        return [_draw(v, rng, key, where) for v in value]
    if not isinstance(value, dict):
        return value
    _check_draw(value, key, where)
    (name, pair), = value.items()
    (a, unit), (b, _) = (_number(v, key, where) for v in pair)
    if name == "uniform":
        x = float(rng.uniform(a, b))
    elif name == "loguniform":
        x = float(math.exp(rng.uniform(math.log(a), math.log(b))))
    else:
        x = float(rng.normal(a, b))
    return f"{x!r} {unit}" if unit else x


def _rng(seed: int, key: str) -> Any:
    """The generator of ``key``'s draws for a member of ``seed``: the same seed draws the same
    truth in every variant (common random numbers across the grid)."""
    import numpy as np

    return np.random.default_rng([seed, zlib.crc32(key.encode())])


def resolve_protocol_path(ref: str, base: Path, source: str) -> Path:
    """A protocol reference as a file: ``paper:NAME`` or a path (a protocol file or a script)
    relative to the campaign file."""
    from gelrig.protocols.spec import paper_protocol

    if ref.startswith("paper:"):
        try:
            return paper_protocol(ref.split(":", 1)[1])
        except ConfigError:
            raise ConfigError("[campaign] protocol", ref,
                              "allowed: a protocol file, paper:compression or paper:shear",
                              source) from None
    path = Path(ref) if Path(ref).is_absolute() else base / ref
    if not path.is_file():
        raise ConfigError("[campaign] protocol", ref, "no such protocol file (paths are "
                          "relative to the campaign file)", source)
    return path


def _param_target(key: str, protocol: Any, where: Where) -> tuple[int, str, Any]:
    """(step index, TOML field, spec) of a ``[params]`` key ``step[i].field`` or
    ``<step name>.field``."""
    head, dot, name = key.rpartition(".")
    steps = protocol.steps
    index: int | None = None
    if dot and head.startswith("step[") and head.endswith("]") and head[5:-1].isdigit():
        index = int(head[5:-1])
    elif dot:
        index = next((i for i, s in enumerate(steps) if s.name == head), None)
    names = ", ".join(f"step[{i}] ({s.name})" for i, s in enumerate(steps))
    if index is None or not 0 <= index < len(steps):
        raise where.error(key, "?", f"name a step and a field as step[i].field or "
                          f"'<step name>.field'; steps: {names}")
    specs = {s.key: s for s in steps[index].definition.Params.specs().values()}
    if name not in specs:
        raise where.error(key, "?", f"unknown field of step[{index}] ({steps[index].kind}); "
                          f"allowed: {', '.join(sorted(specs))}")
    return index, name, specs[name]


def _member_id(payload: Mapping[str, Any]) -> str:
    """A stable id: a hash of the member's canonical description."""
    import hashlib
    import json

    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _check_run_bounds(protocol: Any, param_grid: Mapping[str, list[Any]],
                      targets: Mapping[str, tuple[int, str]], rig: Any, source: str) -> None:
    """Refuse a grid whose largest member would run beyond a run's bounds (samples, lab
    time; protocols/bounds.py). A step's plan depends on its own parameters only, so the
    largest member is each step at its largest: every step is planned over the combinations
    of its own axes (at most the member count), not the whole grid."""
    from gelrig.protocols.bounds import run_bound_error
    from gelrig.protocols.spec import make_step

    plans = []
    for index, step in enumerate(protocol.steps):
        keys = [k for k, (i, _) in targets.items() if i == index]
        best = None
        for combo in itertools.product(*(param_grid[k] for k in keys)):
            raw = dict(protocol.table["step"][index])
            raw.update({targets[k][1]: v for k, v in zip(keys, combo, strict=True)})
            where = Where(f"step[{index}]", source)
            trial = make_step(raw.get("kind"), raw.get("name"), raw, protocol.rig, where,
                              protocol.sample)
            plan = trial.definition.plan(trial.params, rig.limits)
            if best is None or (plan.samples, plan.duration) > (best.samples, best.duration):
                best = plan
        if best is not None:
            plans.append((f"step[{index}] ({step.name})", best))
    beyond = run_bound_error(plans)
    if beyond is not None:
        raise ConfigError(f"[params] {beyond.field}", beyond.value,
                          f"{beyond.allowed} (the grid's largest member)", source)


def parse_campaign(table: dict[str, Any], source: str = "<campaign>",
                   base: Path | None = None) -> CampaignSpec:
    """Validate a campaign given as a TOML table and expand its members."""
    from gelrig.protocols.rigfile import default_rig, parse_rig
    from gelrig.protocols.script import load_script
    from gelrig.protocols.spec import load_protocol, parse_protocol

    base = Path(".") if base is None else base
    allowed = {"campaign", "analysis", "simulator", "params"}
    for key in table:
        if key not in allowed:
            raise ConfigError(f"[{key}]", "?", "unknown table; allowed: [campaign], "
                              "[analysis], [simulator], [params]", source)
        if not isinstance(table[key], dict):
            raise ConfigError(f"[{key}]", table[key], "a table is required here", source)
    head = dict(table.get("campaign") or {})
    where = Where("campaign", source)
    for key in ("protocol",):
        if not isinstance(head.get(key), str) or not head[key].strip():
            raise where.error(key, head.get(key, "missing"), "a protocol file, "
                              "paper:compression or paper:shear")
    ref = head.pop("protocol")
    name = head.pop("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip():
        raise where.error("name", name, "a non-empty string")
    rig_ref = head.pop("rig", None)
    numbers = read_table(head, _HEAD, where)
    protocol_path = resolve_protocol_path(ref, base, source)
    script = load_script(protocol_path) if ref.endswith(SCRIPT_SUFFIXES) else None
    protocol = script if script is not None else load_protocol(protocol_path)
    if script is None and any("repeat" in t for t in protocol.table["step"]):
        # [params] name a file's step tables by index: one table, one step
        raise where.error("protocol", ref, "uses repeat; a campaign varies protocol files "
                          "whose steps are written out, one [[step]] each")
    if rig_ref is None:
        rig_path = default_rig(protocol.rig)
    else:
        if not isinstance(rig_ref, str):
            raise where.error("rig", rig_ref, "a rig file path (relative to this file)")
        rig_path = Path(rig_ref) if Path(rig_ref).is_absolute() else base / rig_ref
        if not rig_path.is_file():
            raise where.error("rig", rig_ref, "no such rig file (paths are relative to the "
                              "campaign file)")
    rig_table = read_toml(rig_path, "rig file")
    rig = parse_rig(rig_table, str(rig_path))
    if rig.kind != protocol.rig:
        raise where.error("rig", rig_ref or str(rig_path), f"is a {rig.kind} rig; the "
                          f"protocol needs a {protocol.rig} rig")
    analysis = Analysis.from_table(table.get("analysis") or {}, source)
    if analysis.unloading == "truth" and rig.kind != "shear":
        raise ConfigError("[analysis] unloading", "truth", "a shear rig's option", source)

    # [simulator]: every grid value checked by the rig file's own parser
    sim_where = Where("simulator", source)
    truth_grid: dict[str, list[Any]] = {}
    draws: dict[str, Any] = {}
    for key, raw in dict(table.get("simulator") or {}).items():
        if key in _SIM_RESERVED:
            raise sim_where.error(key, raw, "set by the campaign: [campaign] replicates and "
                                  "first_seed")
        if _has_draw(raw):  # drawn per member from its seed; checked with a first draw
            trial = copy.deepcopy(rig_table)
            trial.setdefault("simulator", {})[key] = _draw(raw, _rng(0, key), key, sim_where)
            parse_rig(trial, source)
            draws[key] = raw
            continue
        truth_grid[key] = _grid(key, raw, _SIM_DEPTH.get(key, 0), sim_where)

    # [params]: the grid axes, each value checked below by the protocol file's own parser
    par_where = Where("params", source)
    param_grid: dict[str, list[Any]] = {}
    targets: dict[str, tuple[int, str]] = {}
    for key, raw in dict(table.get("params") or {}).items():
        if script is not None:  # a script's parameters: its function's, by name
            param_grid[key] = _grid(key, raw, _depth(script.parameters().get(key)), par_where)
            continue
        index, fname, spec = _param_target(key, protocol, par_where)
        param_grid[key] = _grid(key, raw, 1 if isinstance(spec, FieldList) else 0, par_where)
        targets[key] = (index, fname)

    replicates, first_seed = int(numbers["replicates"]), int(numbers["first_seed"])
    # the grid's size by arithmetic, before any member (or grid value) is made
    axes = {**{f"[simulator] {k}": len(v) for k, v in truth_grid.items()},
            **{f"[params] {k}": len(v) for k, v in param_grid.items()}}
    count = math.prod(axes.values()) * replicates
    if count > MAX_MEMBERS:
        shape = " x ".join(f"{n:,} ({k})" for k, n in axes.items() if n > 1)
        raise ConfigError("members", f"{count:,}", f"at most {MAX_MEMBERS:,} per campaign "
                          f"({shape + ' x ' if shape else ''}{replicates:,} replicates); "
                          "narrow a grid or run fewer replicates", source)
    for key, values in truth_grid.items():
        for value in values:
            trial = copy.deepcopy(rig_table)
            trial.setdefault("simulator", {})[key] = value
            parse_rig(trial, source)
    for key, values in param_grid.items():
        if script is not None:
            try:
                script.with_params(**{key: values[0]})
            except ConfigError as exc:
                raise par_where.error(key, "?", exc.allowed) from None
            continue
        index, fname = targets[key]
        for value in values:
            trial = copy.deepcopy(protocol.table)
            trial["step"][index][fname] = value
            parse_protocol(trial, source)
    if script is None:
        _check_run_bounds(protocol, param_grid, targets, rig, source)
    # only the options set away from their defaults: a new option leaves the ids as they were
    changed = {k: v for k, v in dataclasses.asdict(analysis).items()
               if v != getattr(Analysis(), k)}
    members = []
    truth_keys, param_keys = list(truth_grid), list(param_grid)
    combos = itertools.product(itertools.product(*truth_grid.values()),
                               itertools.product(*param_grid.values()),
                               range(first_seed, first_seed + replicates))
    for n, (tvals, pvals, seed) in enumerate(combos):
        truth = dict(zip(truth_keys, tvals, strict=True))
        params = dict(zip(param_keys, pvals, strict=True))
        member_rig = copy.deepcopy(rig_table)
        member_rig.setdefault("simulator", {}).update(truth, seed=seed)
        for key, raw in draws.items():  # the truth column holds the draw; the variant, raw
            member_rig["simulator"][key] = drawn = _draw(raw, _rng(seed, key), key, sim_where)
            try:
                parse_rig(member_rig, source)
            except ConfigError as exc:
                raise sim_where.error(key, drawn, f"drawn for seed {seed} from {raw}, but "
                                      f"{exc.allowed}; narrow the distribution") from None
        truth = {**truth, **draws}
        if script is not None:
            payload = {"protocol": ref, "script": script.table["protocol"].get("sha256"),
                       "rig": member_rig, "params": params, "analysis": changed, "seed": seed}
            members.append(MemberSpec(n, _member_id(payload), seed, truth, params, member_rig,
                                      str(protocol_path.resolve()), None, analysis))
            continue
        member_protocol = copy.deepcopy(protocol.table)
        for key, value in params.items():
            index, fname = targets[key]
            member_protocol["step"][index][fname] = value
        payload = {"protocol": ref, "rig": member_rig, "steps": member_protocol["step"],
                   "analysis": changed, "seed": seed}
        members.append(MemberSpec(n, _member_id(payload), seed, truth, params, member_rig,
                                  ref, member_protocol, analysis))
    return CampaignSpec(str(name), source, ref, rig.kind, replicates, first_seed, analysis,
                        truth_grid, param_grid, tuple(members), table)


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign file; paths in it are relative to it."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("CAMPAIGN", str(path), "no such campaign file")
    return parse_campaign(read_toml(path, "campaign file"), str(path), path.parent)
