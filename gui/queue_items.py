"""What the queue holds (issue 28, item 6; ADR 0371): items that each name a protocol file or
script with its parameter values, the sample and the run record, kept in a JSON file.

A parameter of a protocol file is named as a campaign's ``[params]`` names it:
``step[1].hold`` or ``<step name>.hold``; a script's by its keyword (``hold``). Values are
typed as on the command line (``--param``): a TOML value, a bare word or ``20 s`` a string.
A sweep over one parameter is one item per value. Nothing here touches Qt or the rig.
"""

from __future__ import annotations

import contextlib
import copy
import json
import os
import time
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.procedure import Procedure
from gelrig.protocols.resolve import parse_params, resolve_procedure
from gelrig.protocols.runinfo import RunInfo, run_info

#: Format version of the queue file.
VERSION = 1
#: An item's states: waiting, being rehearsed, on the rig now, done, or where the queue
#: stopped.
QUEUED, REHEARSING, RUNNING = "queued", "rehearsing", "running"
COMPLETED, STOPPED = "completed", "stopped"


@dataclass
class QueueItem:
    """One queued run: ``path`` (a .toml protocol or a .py script), ``params`` (name ->
    value as typed), ``sample`` (a ``[sample]`` table, {} for the protocol's own),
    ``operator``/``note``/``tags`` (the run record), ``state`` and ``reason``."""

    path: str
    params: dict[str, str] = field(default_factory=dict)
    sample: dict[str, Any] = field(default_factory=dict)
    operator: str = ""
    note: str = ""
    tags: list[str] = field(default_factory=list)
    state: str = QUEUED
    reason: str = ""
    run: str = ""  # the run folder, once started

    def label(self) -> str:
        """``hold.toml  step[1].hold=20 s  (gel-A1)``."""
        parts = [Path(self.path).name, *(f"{k}={v}" for k, v in self.params.items())]
        if self.sample.get("name"):
            parts.append(f"({self.sample['name']})")
        return "  ".join(parts)

    def info(self) -> RunInfo:
        return run_info(self.operator or None, self.note, self.tags, option="")

    def procedure(self) -> Procedure:
        """The procedure to run: the file read now with the parameter values and the sample
        (a ConfigError naming the parameter, the value and what is allowed)."""
        sample = self.sample or None
        if Path(self.path).suffix == ".py":
            params = parse_params([f"{k}={v}" for k, v in self.params.items()])
            return resolve_procedure(self.path, params, sample=sample)
        try:
            table = tomllib.loads(Path(self.path).read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError("protocol", self.path, f"a readable protocol file ({exc})"
                              ) from None
        for key, text in self.params.items():
            set_param(table, key, value_of(text), self.path)
        return resolve_procedure(self.path, table=table, sample=sample)


def value_of(text: str) -> Any:
    """A value as ``--param`` reads it: TOML (``0.04``, ``[1, 2]``), else the text."""
    return parse_params([f"v={text}"])["v"]


def set_param(table: dict[str, Any], key: str, value: Any, source: str) -> None:
    """Set ``step[i].field`` or ``<step name>.field`` of a protocol file's table."""
    raw = table.get("step")
    steps: list[Any] = raw if isinstance(raw, list) else []
    head, dot, name = key.rpartition(".")
    index = None
    if dot and head.startswith("step[") and head.endswith("]") and head[5:-1].isdigit():
        index = int(head[5:-1])
    elif dot:
        index = next((i for i, s in enumerate(steps) if isinstance(s, dict)
                      and s.get("name") == head), None)
    if index is None or not 0 <= index < len(steps) or not name:
        names = ", ".join(f"step[{i}]" for i in range(len(steps)))
        raise ConfigError("parameter", key, f"step[i].field or '<step name>.field' of "
                          f"{source} (steps: {names})")
    steps[index][name] = value


def split_values(text: str) -> list[str]:
    """A sweep's values: separated by ``;``, or by ``,`` outside brackets."""
    if ";" in text:
        return [v.strip() for v in text.split(";") if v.strip()]
    out, depth, current = [], 0, ""
    for char in text:
        depth += (char in "[{") - (char in "]}")
        if char == "," and depth == 0:
            out.append(current)
            current = ""
        else:
            current += char
    out.append(current)
    return [v.strip() for v in out if v.strip()]


def sweep(base: QueueItem, name: str, values: list[str]) -> list[QueueItem]:
    """One item per value of parameter ``name`` (the others as in ``base``)."""
    items = []
    for value in values:
        item = copy.deepcopy(base)
        item.params[name] = value
        items.append(item)
    return items


# ---- the file -----------------------------------------------------------------------------
def save_queue(path: Path, items: list[QueueItem]) -> None:
    """Write the queue (atomically: a crash leaves the old file or the new one)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.tmp")
    tmp.write_text(json.dumps({"version": VERSION, "items": [asdict(i) for i in items]},
                              indent=1), encoding="utf-8")
    os.replace(tmp, path)


def load_queue(path: Path) -> tuple[list[QueueItem], str]:
    """The queue kept in ``path`` and a warning line ('' if none). A file that cannot be
    read as a queue is set aside (``<name>.corrupt-<time>``) and the queue starts empty; an
    item left ``running`` by a window that went away is ``stopped``, one left
    ``rehearsing`` is ``queued`` again."""
    if not path.exists():
        return [], ""
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(raw, dict) or raw.get("version") != VERSION:
            raise ValueError(f"not a version-{VERSION} queue")
        items = [QueueItem(**item) for item in raw["items"]]
        for item in items:
            if not isinstance(item.path, str) or not isinstance(item.params, dict):
                raise ValueError("an item without a path or parameters")
    except (OSError, ValueError, TypeError, KeyError) as exc:
        aside = path.with_name(f"{path.name}.corrupt-{time.strftime('%Y%m%d-%H%M%S')}")
        with contextlib.suppress(OSError):
            os.replace(path, aside)
        return [], (f"queue file {path} could not be read ({type(exc).__name__}: "
                    f"{str(exc)[:120]}); set aside as {aside.name}, the queue starts empty")
    for item in items:
        if item.state == RUNNING:
            item.state, item.reason = STOPPED, "the window closed while it ran"
        elif item.state == REHEARSING:  # nothing moved for it: it waits again
            item.state = QUEUED
    return items, ""
