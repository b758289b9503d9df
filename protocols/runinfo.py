"""Who ran a run, and why: the operator, a note and tags, stored in run.json (ADR 0370).

Given on the command line (``gelrig run --operator ada --note "fresh batch" --tag cure2h``)
or to the scripting API (``session.run(..., operator=, note=, tags=)``); the catalog of runs
(``gelrig runs``) lists and filters by them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from gelrig.instrument.core.errors import ConfigError

#: Longest operator name or tag (characters).
MAX_NAME = 100
#: Longest note (characters).
MAX_NOTE = 2000


def check_line(value: object, field: str, longest: int = MAX_NAME, empty: bool = False
               ) -> str:
    """``value`` as one line of text (stripped): a ConfigError naming ``field`` for a
    non-string, a line break or control character, or more than ``longest`` characters."""
    if not isinstance(value, str):
        raise ConfigError(field, value, "a string")
    text = value.strip()
    if not text and not empty:
        raise ConfigError(field, value, "a non-empty string")
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise ConfigError(field, value, "one line of text, without control characters")
    if len(text) > longest:
        raise ConfigError(field, f"{text[:40]}...", f"at most {longest} characters")
    return text


@dataclass(frozen=True)
class RunInfo:
    """The operator, the note and the tags of a run (each may be empty)."""

    operator: str = ""
    note: str = ""
    tags: tuple[str, ...] = ()

    def table(self) -> dict[str, Any]:
        """What run.json holds: ``operator``, ``note``, ``tags`` (always present)."""
        return {"operator": self.operator, "note": self.note, "tags": list(self.tags)}


def run_info(operator: str | None = None, note: str | None = None,
             tags: Iterable[str] | str | None = None, option: str = "--") -> RunInfo:
    """A checked :class:`RunInfo`; ``option`` prefixes the field in errors (``--operator``
    on the command line, ``operator`` in the API)."""
    if isinstance(tags, str):
        tags = [tags]
    checked = []
    for tag in tags or ():
        text = check_line(tag, f"{option}tag")
        if text not in checked:
            checked.append(text)
    return RunInfo(
        "" if operator is None else check_line(operator, f"{option}operator"),
        "" if note is None else check_line(note, f"{option}note", MAX_NOTE, empty=True),
        tuple(checked))
