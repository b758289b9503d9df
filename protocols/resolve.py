"""What a front end names, resolved once: the procedure, the rig and the clock of a run.

One resolver each, used by the CLI, the scripting API, the GUI, ``gelrig demo`` and a
campaign member, so that ``paper:shear``, a protocol file, a script with parameters, a
campaign's protocol table, ``"shear"`` as a rig, a rig file and ``paced:10`` mean the same
everywhere, and their errors read the same (a ConfigError naming the option).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from gelrig.instrument.core.clock import Clock, RealClock
from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.rigfile import KINDS, RigSpec, default_rig, load_rig, parse_rig
from gelrig.protocols.sample import SampleRef, resolve_sample

#: What names a procedure: a file path, ``paper:NAME``, or a procedure already made.
ProcedureRef = str | os.PathLike[str] | Procedure
#: What names a rig: ``"compression"`` / ``"shear"`` (the built-in simulated rigs), a rig
#: file, a rig file's table, or a parsed :class:`RigSpec`.
RigRef = str | os.PathLike[str] | RigSpec


def resolve_procedure(ref: ProcedureRef, params: Mapping[str, Any] | None = None,
                      table: Mapping[str, Any] | None = None,
                      sample: SampleRef | None = None, check: bool = True) -> Procedure:
    """The procedure ``ref`` names: a protocol file (``.toml``), a script (``.py``), a
    shipped paper protocol (``paper:compression``), or a procedure as it is. ``table`` is a
    protocol file's table already read (a campaign's, parsed here once with ``ref`` as its
    source); ``params`` a script's keyword parameters (a protocol file takes none: its
    parameters are in the file); ``sample`` the run's sample (a Sample, a table, a sample
    file), replacing a protocol file's ``[sample]``. A script parameter without a default
    that is not given is a ConfigError naming it, before anything is built (unless not
    ``check``: a script loaded to be given its parameters later)."""
    from gelrig.protocols.script import Script, load_procedure
    from gelrig.protocols.spec import ProtocolSpec, parse_protocol

    if table is not None:
        procedure: Procedure = parse_protocol(dict(table), os.fspath(ref) if isinstance(
            ref, str | os.PathLike) else "<table>")
    elif isinstance(ref, str | os.PathLike):
        procedure = load_procedure(os.fspath(ref))
    else:
        procedure = ref
    if sample is not None:
        if not isinstance(procedure, ProtocolSpec | Script):
            raise ConfigError("sample", procedure.source, "only protocol files and scripts "
                              "take a sample")
        procedure = procedure.with_sample(resolve_sample(sample, procedure.sample))
    if params:
        if not isinstance(procedure, Script):
            raise ConfigError("--param", next(iter(params)), "only scripts (.py) take "
                              "parameters; a protocol file's are in the file")
        procedure = procedure.with_params(**params)
    if check and isinstance(procedure, Script):
        procedure.check_params()
    return procedure


def parse_params(texts: list[str]) -> dict[str, object]:
    """``NAME=VALUE`` options (``--param``), VALUE read as a TOML value (a bare word stays a
    string)."""
    import tomllib

    out: dict[str, object] = {}
    for text in texts:
        name, eq, value = text.partition("=")
        if not eq or not name.strip().isidentifier():
            raise ConfigError("--param", text, "NAME=VALUE, e.g. hold='600 s' or strain=0.04")
        try:
            out[name.strip()] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out[name.strip()] = value
    return out


def resolve_rig(ref: RigRef | Mapping[str, Any] | None = None,
                procedure: Procedure | None = None, source: str = "<rig>") -> RigSpec:
    """The rig ``ref`` names (None: the built-in simulated rig of the procedure's kind),
    checked against the procedure's rig kind (a ConfigError naming ``--rig``)."""
    if ref is None:
        if procedure is None:
            raise ConfigError("--rig", "missing", "name a rig file or a rig kind "
                              f"({', '.join(KINDS)})")
        ref = procedure.rig
    if isinstance(ref, Mapping):
        rig = parse_rig(dict(ref), source)
    elif isinstance(ref, str | os.PathLike):
        name = os.fspath(ref)
        rig = load_rig(default_rig(name) if name in KINDS else name)
    else:
        rig = ref
    if procedure is not None and rig.kind != procedure.rig:
        raise ConfigError("--rig", rig.source, f"is a {rig.kind} rig; protocol "
                          f"{procedure.source} needs a {procedure.rig} rig")
    return rig


def check_clock(rig: RigSpec, clock: Clock, spec: str) -> None:
    """A virtual or paced clock only makes sense when every instrument is simulated."""
    if not isinstance(clock, RealClock) and not rig.simulated:
        raise ConfigError("--clock", spec, f"rig {rig.source} has real instruments; "
                          "use --clock real (virtual and paced time need a simulated rig)")


def make_clock(clock: str | Clock | None, rig: RigSpec) -> tuple[Clock, str]:
    """The clock of a run on ``rig`` and how run.json names it: ``clock`` as ``real``,
    ``virtual`` or ``paced:K`` (default: virtual on a simulated rig, real otherwise), or a
    Clock; checked against the rig (:func:`check_clock`; errors name ``--clock``)."""
    from gelrig.instrument.core.clock import clock_from_spec

    if clock is None:
        clock = "virtual" if rig.simulated else "real"
    if isinstance(clock, str):
        try:
            made, text = clock_from_spec(clock), clock
        except ConfigError as exc:
            raise ConfigError("--clock", exc.value, exc.allowed) from None
    else:
        made, text = clock, type(clock).__name__.removesuffix("Clock").lower()
    check_clock(rig, made, text)
    return made, text
