"""Scripts as protocols: a Python function that decides its steps as it runs.

A script is a function decorated with :func:`protocol`; it receives a :class:`Run` and asks
it for steps, built-in or user-defined, with the same parameters as a protocol file::

    @protocol(rig="compression", name="Relaxation series")
    def series(run: Run) -> None:
        run.step("compression_contact_search", speed="0.3 mm/s")
        for strain in (0.02, 0.04, 0.06):
            run.step("ramp_hold", name=f"hold at {strain:.0%}", strain=strain, hold="600 s")

Every step runs through the runner exactly as a protocol file's step does: preflight against
the rig's caps, interlocks on every sample, pause at checkpoints, abort at every block, its
columns streamed to the run directory. A resumed run calls the script again from the top;
steps the run completed before are not run again, :meth:`Run.step` returns their stored
results, so a script must ask for the same steps in the same order given the same results
(it is refused otherwise: :class:`gelrig.protocols.runner.ReplayMismatch`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gelrig.instrument.core.errors import ConfigError, shown
from gelrig.instrument.core.fields import Where
from gelrig.protocols.origin import origin, user_site
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.sample import Sample, parse_sample
from gelrig.protocols.spec import (
    RIGS,
    Step,
    StepSink,
    load_protocol,
    make_step,
    paper_protocol,
    parse_protocol,
)
from gelrig.protocols.steps import KINDS, import_file
from gelrig.protocols.steps.base import StepDefinition, StepResult

Body = Callable[["Run"], None]


@dataclass(frozen=True)
class Script:
    """A script protocol: its function, the rig kind it runs on, its name and file. A
    :class:`gelrig.protocols.procedure.Procedure` whose steps are known only as it runs."""

    function: Body
    rig: str
    name: str
    description: str = ""
    #: the file the function is defined in (what run.json records, and a resume loads)
    path: str = ""
    #: keyword arguments the function is called with (``gelrig run --param``, a campaign's
    #: ``[params]``); the function's defaults stand for the others
    params: Mapping[str, Any] = field(default_factory=dict)
    #: the run's sample: steps that need a size (``ramp_hold``'s diameter) take it from here
    sample: Sample | None = None

    def parameters(self) -> dict[str, Any]:
        """The function's own parameters (after ``run``) with their defaults (``None`` when it
        has none)."""
        signature = inspect.signature(self.function)
        return {name: (None if p.default is inspect.Parameter.empty else p.default)
                for name, p in list(signature.parameters.items())[1:]
                if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}

    def with_params(self, **values: Any) -> Script:
        """This script called with ``values`` as keyword arguments (on top of any set
        before); a name the function does not take is a ConfigError listing those it does."""
        known = self.parameters()
        for name in values:
            if name not in known:
                raise ConfigError("script parameter", name,
                                  f"{Path(self.source).name} takes "
                                  f"{', '.join(known) or 'no parameters'}")
        return dataclasses.replace(self, params={**self.params, **values})

    def with_sample(self, sample: Sample) -> Script:
        """This script measuring ``sample``."""
        return dataclasses.replace(self, sample=sample)

    def missing(self) -> list[str]:
        """The function's parameters without a default that were not given."""
        signature = inspect.signature(self.function)
        return [name for name, p in list(signature.parameters.items())[1:]
                if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
                and p.default is inspect.Parameter.empty and name not in self.params]

    def check_params(self) -> None:
        """A ConfigError naming the first parameter without a default that was not given (a
        call would end in a TypeError); before anything is built."""
        missing = self.missing()
        if missing:
            name = missing[0]
            raise ConfigError("script parameter", name, f"required by "
                              f"{Path(self.source).name} (it has no default); give it as "
                              f"--param {name}=VALUE (API: params={{{name!r}: ...}})")

    @property
    def source(self) -> str:
        return self.path or f"<script {self.function.__qualname__}>"

    @property
    def steps(self) -> tuple[Step, ...]:
        return ()

    @property
    def table(self) -> dict[str, Any]:
        head: dict[str, Any] = {"name": self.name, "rig": self.rig,
                                "description": self.description,
                                "script": self.path, "entry": self.function.__name__,
                                "params": dict(self.params)}
        if self.sample is not None:
            head["sample"] = self.sample.table()
        if self.path and Path(self.path).is_file():
            head["sha256"] = hashlib.sha256(Path(self.path).read_bytes()).hexdigest()
        return {"protocol": head}

    def drive(self, sink: StepSink) -> None:
        self.check_params()
        self.function(Run(sink, self), **self.params)


def protocol(rig: str, name: str | None = None, description: str = "") -> Callable[[Body],
                                                                                   Script]:
    """Decorator: make ``function(run)`` a protocol for the ``rig`` kind ("compression" or
    "shear"), named ``name`` (default: the function's name)."""
    if rig not in RIGS:
        raise ConfigError("protocol(rig=...)", rig, f"allowed: {', '.join(RIGS)}")

    def wrap(function: Body) -> Script:
        code = getattr(function, "__code__", None)
        path = str(Path(code.co_filename).resolve()) if code is not None else ""
        doc = (function.__doc__ or "").strip()
        return Script(function, rig, name or function.__name__.replace("_", " "),
                      description or doc, path)

    return wrap


class Run:
    """What a script's function receives: it asks for steps, checkpoints and log lines.

    Motions belong in steps (built-in kinds, or your own :class:`StepDefinition`), where the
    rig's interlocks watch every sample; the run itself exposes the rig only to read it.
    """

    def __init__(self, sink: StepSink, script: Script):
        self._sink = sink
        self._script = script
        self._count = 0
        #: every step's typed result so far, in order (replayed ones too)
        self.results: list[StepResult] = []

    @property
    def rig_kind(self) -> str:
        return self._script.rig

    @property
    def sample(self) -> Sample | None:
        """The run's sample (name, sizes in m, material), None when none was given."""
        return self._script.sample

    def step(self, kind: str | StepDefinition[Any, Any, Any] | type, name: str | None = None,
             **params: Any) -> Any:
        """Run the next step and return its typed result (e.g. a ``RampHoldResult``).

        ``kind``: a step kind's name as protocol files write it (``"ramp_hold"``), or a step
        definition (class or instance). ``params``: the same keys and values as in a
        protocol file, unit strings (``hold="600 s"``) or SI numbers; checked the same way
        (a bad value is a ConfigError naming the script, the step and the field)."""
        index = self._count
        self._count += 1
        where = Where(f"step[{index}]", self._script.source)
        try:
            built = make_step(kind, name, params, self._script.rig, where, self._script.sample)
        except ConfigError as exc:  # a bad value, field or kind: refused, like a cap
            at = origin(exc) or user_site(sys._getframe())
            field = exc.field.removeprefix(f"[{where.section}] ")
            self._sink.refuse(_step_name(kind, name),
                              f"{field} = {shown(exc.value)}: {exc.allowed}"
                              + (f" (at {at})" if at else ""))
        result = self._sink.step(built)
        self.results.append(result)
        return result

    def checkpoint(self) -> None:
        """A point between steps where a requested pause takes effect (nothing moves)."""
        self._sink.checkpoint()

    def log(self, message: str) -> None:
        """A line in the run's log (RUN_DIR/gelrig.log), also shown on the console when the
        run shows its progress (``gelrig run``, ``show=True``)."""
        self._sink.note(str(message))


def _step_name(kind: object, name: object) -> str:
    """What a step asked for is called in a refusal's line: its name, else its kind's."""
    if isinstance(name, str):
        return name
    definition = getattr(kind, "kind", kind)
    known = KINDS.get(definition) if isinstance(definition, str) else None
    return (known.description or known.kind) if known is not None else str(definition)


def load_script(path: str | Path, entry: str | None = None) -> Script:
    """Import a script file and return the protocol it defines (the one decorated with
    :func:`protocol`; ``entry`` picks one by function name when it defines several)."""
    file = Path(path).resolve()
    if file.suffix != ".py":
        raise ConfigError("script", str(path), "a Python file (.py)")
    module = import_file(file, "script", None)
    found = {v.function.__name__: v for v in vars(module).values() if isinstance(v, Script)}
    if entry is not None:
        if entry not in found:
            raise ConfigError("script entry", entry, f"not a protocol of {file.name}; it "
                              f"defines {', '.join(found) or 'none'}")
        return found[entry]
    if len(found) != 1:
        what = (f"{len(found)} ({', '.join(found)})" if found else "none")
        raise ConfigError("script", str(path), f"defines {what} protocols; a script defines "
                          "one function decorated with @gelrig.protocol(rig=...)")
    return next(iter(found.values()))


#: Folder of a run directory that keeps a copy of the script that made it.
COPY_DIR = "script"


def script_from_table(table: Mapping[str, Any], source: str, run_dir: Path
                      ) -> tuple[Script, list[str]]:
    """The script a run.json's protocol table records (for resume): from its file, or from
    the copy in the run directory when the file is gone; notes say which and whether it
    changed since."""
    head = table.get("protocol") if isinstance(table, Mapping) else None
    if not isinstance(head, Mapping) or not isinstance(head.get("script"), str):
        raise ConfigError("protocol.script", "missing", "run.json of a script run names its "
                          "script", source)
    path = Path(head["script"])
    notes = []
    if not path.is_file():
        copy = run_dir / COPY_DIR / path.name
        if not copy.is_file():
            raise ConfigError("protocol.script", str(path), "is gone, and the run directory "
                              "holds no copy of it", source)
        notes.append(f"{path} is gone; resuming with the run's copy {copy}")
        path = copy
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if head.get("sha256") and digest != head["sha256"]:
        notes.append(f"{path.name} changed since the run started; completed steps replay by "
                     "name and kind")
    script = load_script(path, str(head.get("entry") or "") or None)
    params = head.get("params") or {}
    if not isinstance(params, Mapping):
        raise ConfigError("protocol.params", params, "a table of the script's parameters",
                          source)
    script = script.with_params(**params)
    if "sample" in head:
        script = script.with_sample(parse_sample(head["sample"], source))
    return script, notes


def procedure_from_table(table: Mapping[str, Any], source: str,
                         run_dir: Path) -> tuple[Procedure, list[str]]:
    """What run.json's ``protocol`` table holds, ready to run again (resume): a protocol
    file's steps, or the script it names; and notes for people (a script that changed). An
    interactive run's table is refused in one line saying how to continue it from Python."""
    from gelrig.protocols.interactive import ResumeFromPython, is_interactive

    if is_interactive(table):
        raise ResumeFromPython(str(run_dir))
    head = table.get("protocol") if isinstance(table, Mapping) else None
    if isinstance(head, Mapping) and "script" in head:
        return script_from_table(table, source, run_dir)
    return parse_protocol(dict(table), source), []


def load_procedure(reference: str) -> Procedure:
    """A protocol file, a script (``.py``) or a shipped paper protocol (``paper:shear``)."""
    if reference.startswith("paper:"):
        return load_protocol(paper_protocol(reference.split(":", 1)[1]))
    if reference.endswith(".py"):
        return load_script(reference)
    return load_protocol(reference)
