"""The sample a run measures: its name, its size and notes on its material.

A run's sample is an input, never a default (docs/decisions/0280): a protocol file states it
in a ``[sample]`` table, a script gets it from the run (``gelrig run --sample-diameter "12 mm"``
or ``--sample FILE.toml``, ``session.run(..., sample=...)``), and every step that needs a size
takes it from there (:data:`gelrig.protocols.steps.base.StepDefinition.sample_fields`). A step
that needs a size nobody gave is refused before anything moves, naming the field::

    [sample]
    name = "PDMS sphere A3"
    diameter = "12 mm"          # compression: the sphere's diameter
    material = "Sylgard 184, 10:1, cured 2 h at 80 C"

    # shear: the two spheres' radii
    r1 = "9.2 mm"               # upper sphere, on the arm
    r2 = "9.96 mm"              # lower sphere, fixed
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import Config, Field, Text, Where, param, read_toml

#: Where a size a step needs can be given, for the one-line error when none was.
HOW_TO_GIVE = ("it as the run's sample: [sample] {key} in the protocol file, --sample FILE.toml "
               "or --sample-diameter on the command line, sample= in the scripting API")


class SampleSizeMissing(ConfigError):
    """A step needs a size of the sample (``size``: ``diameter``, ``r1``, ``r2``) and none was
    given: the run is refused before anything moves (the GUI points at its Sample fields)."""

    def __init__(self, field: str, allowed: str, source: str | None, size: str):
        super().__init__(field, "missing", allowed, source)
        self.size = size

    def __reduce__(self) -> tuple[type[SampleSizeMissing], tuple[str, str, str | None, str]]:
        return type(self), (self.field, self.allowed, self.source, self.size)


DIAMETER = Field("diameter", "m", None, 0.0, 0.1, lo_open=True, optional=True, display="mm",
                 help="sphere diameter (compression rig)")


@dataclass(frozen=True)
class Sample(Config):
    """A run's sample: a name, the sizes the steps use (SI, m) and notes (``material``)."""

    section: ClassVar[str] = "sample"

    name: str = param(Text("name", "", "a string", lambda s: True, help="what the sample is"))
    diameter: float | None = param(DIAMETER)
    r1: float | None = param(Field(
        "r1", "m", None, 0.0, 0.05, lo_open=True, optional=True, display="mm",
        help="radius of the upper sphere, on the arm (shear rig)"))
    r2: float | None = param(Field(
        "r2", "m", None, 0.0, 0.05, lo_open=True, optional=True, display="mm",
        help="radius of the lower, fixed sphere (shear rig)"))
    material: str = param(Text("material", "", "a string", lambda s: True,
                               help="notes on the material (recipe, cure, batch)"))

    def table(self) -> dict[str, Any]:
        """What run.json and a protocol file's ``[sample]`` hold: the values given (SI)."""
        return {k: v for k, v in self.to_table().items() if v not in (None, "")}

    def size(self, key: str) -> float | None:
        """The size ``key`` (``diameter``, ``r1``, ``r2``) in m, None when not given."""
        value = getattr(self, key, None)
        return float(value) if isinstance(value, int | float) and math.isfinite(value) else None

    def describe(self) -> str:
        """One line for people: ``PDMS A3: diameter 12 mm (Sylgard 184)``."""
        sizes = ", ".join(f"{k} {v * 1e3:g} mm" for k in ("diameter", "r1", "r2")
                          if (v := self.size(k)) is not None)
        head = self.name or "sample"
        text = f"{head}: {sizes or 'no size given'}"
        return f"{text} ({self.material})" if self.material else text


def parse_sample(raw: object, source: str | None = None) -> Sample:
    """A ``[sample]`` table (unit strings or SI numbers) as a :class:`Sample`."""
    if not isinstance(raw, Mapping):
        raise ConfigError("[sample]", raw, "a table: name, diameter, r1, r2, material", source)
    return Sample.from_table(raw, source)


#: What names a sample: a Sample, a table (``{"diameter": "12 mm"}``), or a TOML file
#: holding a ``[sample]`` table.
SampleRef = Sample | Mapping[str, Any] | str | os.PathLike[str]


def resolve_sample(ref: SampleRef, base: Sample | None = None) -> Sample:
    """The sample ``ref`` names (a ConfigError naming the field or the file otherwise): a
    string that is not a sample file is a sample name, renaming ``base`` (the protocol's
    own sample, its sizes kept)."""
    if isinstance(ref, Sample):
        return ref
    if isinstance(ref, Mapping):
        return parse_sample(ref, "sample")
    if isinstance(ref, str) and not is_sample_file(ref):
        return named(check_sample_name(ref, "sample"), base)
    path = os.fspath(ref)
    table = read_toml(path, "sample file")
    inner = table.get("sample")
    if not isinstance(inner, Mapping):
        raise ConfigError("[sample]", "missing", "a sample file holds a [sample] table "
                          "(name, diameter or r1 and r2, material)", path)
    unknown = set(table) - {"sample"}
    if unknown:
        raise ConfigError(sorted(unknown)[0], "?", "unknown table; a sample file holds "
                          "[sample] only", path)
    return parse_sample(inner, path)


#: Longest sample name (characters): it becomes part of the run folder's name.
MAX_NAME = 80


def check_sample_name(name: object, field: str = "--sample") -> str:
    """A sample name that can name a run folder: one line, no path separator, not ``.`` or
    ``..``, at most MAX_NAME characters (a ConfigError naming ``field`` otherwise)."""
    allowed = (f"a sample name: one line of at most {MAX_NAME} characters, without / or \\ "
               "(it names the run folder), or a sample file (.toml)")
    if not isinstance(name, str):
        raise ConfigError(field, name, allowed)
    text = name.strip()
    if (not text or text in (".", "..") or len(text) > MAX_NAME
            or any(c in "/\\" or ord(c) < 32 or ord(c) == 127 for c in text)):
        raise ConfigError(field, name if len(name) <= 60 else f"{name[:60]}...", allowed)
    return text


def is_sample_file(ref: str) -> bool:
    """Whether ``--sample REF`` names a sample file (a .toml path, or a file that exists)
    rather than a sample name."""
    return ref.lower().endswith(".toml") or os.path.isfile(ref)


def named(name: str, base: Sample | None) -> Sample:
    """``base`` (the protocol's sample: its sizes and material) under the name ``name``."""
    if base is None:
        return Sample(name)
    return Sample(name, base.diameter, base.r1, base.r2, base.material)


def sample_from_options(file: str | None, diameter: str | None,
                        base: Sample | None = None) -> Sample | None:
    """``--sample NAME|FILE.toml`` and ``--sample-diameter "12 mm"`` as one sample (the
    diameter given replaces the file's); None when neither is given. A NAME (not a .toml
    file) renames ``base``, the protocol's own sample, keeping its sizes (ADR 0370)."""
    if file is None and diameter is None:
        return None
    if file is not None and not is_sample_file(file):
        sample = named(check_sample_name(file), base)
    else:
        sample = resolve_sample(file) if file is not None else Sample()
    if diameter is not None:
        spec = dataclasses.replace(DIAMETER, key="--sample-diameter")
        value = spec.parse(diameter, Where())
        sample = Sample(sample.name, value, sample.r1, sample.r2, sample.material)
    return sample
