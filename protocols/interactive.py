"""An interactive run: a procedure whose steps come one at a time from a person at a REPL or
notebook, each run on the run host's thread as it arrives.

The run is an ordinary run of the host (one run directory, one runner, its recorder, caps,
interlocks, watchdog and safe stop); only its procedure differs: :meth:`Interactive.drive`
waits on a :class:`StepFeed` for the next step and hands it to the runner, until the caller
ends the run, or raises into it what left the caller's block (an exception: the run ends
failed; Ctrl-C: aborted; either after the runner's safe stop). A resumed interactive run
first sends the steps it completed before, which the runner replays from run.json (their
stored results come back, nothing moves), so later steps see their results.
"""

from __future__ import annotations

import queue
from collections.abc import Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.sample import Sample, parse_sample
from gelrig.protocols.spec import Step, StepSink
from gelrig.protocols.steps.base import StepResult

#: What run.json's protocol table says of an interactive run (its ``protocol.interactive``).
MARK = "interactive"
#: The source an interactive run's errors name.
SOURCE = "<interactive>"


class ResumeFromPython(ConfigError):
    """``gelrig resume`` (or :meth:`RigSession.resume`) of an interactive run: its steps were
    a person's, so only Python can add more (one line; nothing is touched)."""

    def __init__(self, run_dir: str):
        line = (f"{run_dir} is an interactive run (its steps were added from Python); "
                "continue it from Python: with gelrig.open_rig(...) as rig: "
                f"rig.run_interactive(resume={run_dir!r})")
        Exception.__init__(self, line)
        self.field, self.value, self.allowed, self.source = "run", run_dir, line, None


class _End:
    """The caller ended the run (normally, or with ``raised``)."""

    def __init__(self, raised: BaseException | None = None):
        self.raised = raised


class StepFeed:
    """The channel from the caller's thread to the run's: steps in, typed results (or what
    the step raised) back through a Future each; then the end."""

    def __init__(self) -> None:
        self._queue: queue.Queue[tuple[Step, Future[StepResult]] | _End] = queue.Queue()

    def submit(self, step: Step) -> Future[StepResult]:
        """Send ``step`` to the run; its Future holds the result (or what ended the run)."""
        reply: Future[StepResult] = Future()
        self._queue.put((step, reply))
        return reply

    def end(self, raised: BaseException | None = None) -> None:
        """End the run: completed (``raised`` None), else the way ``raised`` ends a script
        that raises it (an exception: failed; KeyboardInterrupt: aborted)."""
        self._queue.put(_End(raised))

    def serve(self, sink: StepSink) -> None:
        """On the run's thread: run each step sent until the end."""
        while True:
            item = self._queue.get()
            if isinstance(item, _End):
                if item.raised is not None:
                    raise _copy(item.raised)
                return
            step, reply = item
            if not reply.set_running_or_notify_cancel():
                continue
            try:
                result = sink.step(step)
            except BaseException as exc:  # the run ended short (RunEnded) or Ctrl-C
                reply.set_exception(exc)
                raise
            reply.set_result(result)


def _copy(exc: BaseException) -> BaseException:
    """``exc`` anew for the run's thread (the caller's own, with its traceback, goes on
    propagating there): same type and text, so run.json's reason reads as a script's
    would (``ValueError: ...``)."""
    kind = type(exc)
    try:  # not through __init__: an error's own signature (ConfigError's) need not fit
        made = kind.__new__(kind, *exc.args)
        made.__dict__.update(getattr(exc, "__dict__", {}))
        made.args = exc.args
        return made
    except Exception:
        return RuntimeError(f"{kind.__name__}: {exc}")


@dataclass(frozen=True)
class Interactive:
    """The procedure of an interactive run: steps decided by a person, one at a time
    (:class:`StepFeed`); ``replay`` the steps a resumed run completed before."""

    rig: str
    name: str
    sample: Sample | None = None
    feed: StepFeed = field(default_factory=StepFeed, compare=False, repr=False)
    replay: tuple[Step, ...] = ()

    @property
    def source(self) -> str:
        return SOURCE

    @property
    def steps(self) -> tuple[Step, ...]:
        return ()

    @property
    def table(self) -> dict[str, Any]:
        head: dict[str, Any] = {"name": self.name, "rig": self.rig, MARK: True}
        if self.sample is not None:
            head["sample"] = self.sample.table()
        return {"protocol": head}

    def drive(self, sink: StepSink) -> None:
        for step in self.replay:
            sink.step(step)
        self.feed.serve(sink)


def is_interactive(table: Mapping[str, Any]) -> bool:
    """run.json's protocol table is an interactive run's."""
    head = table.get("protocol") if isinstance(table, Mapping) else None
    return isinstance(head, Mapping) and head.get(MARK) is True


def refuse_interactive(meta: Mapping[str, Any], run_dir: str) -> None:
    """Raise :class:`ResumeFromPython` when run.json ``meta`` is an interactive run's (what
    ``gelrig resume`` and ``RigSession.resume`` check first, completed or not)."""
    if is_interactive(meta.get("protocol") or {}):
        raise ResumeFromPython(run_dir)


def interactive_from_table(table: Mapping[str, Any], source: str,
                           completed: Mapping[int, Mapping[str, Any]]) -> Interactive:
    """The interactive procedure run.json's ``protocol`` table records, with the steps
    ``completed`` (index -> run.json's step record) to replay first: built again from their
    recorded kind, name and parameters (a kind no longer registered is a ConfigError)."""
    from gelrig.instrument.core.fields import Where
    from gelrig.protocols.spec import RIGS, make_step

    head = table.get("protocol") if isinstance(table, Mapping) else None
    if not isinstance(head, Mapping) or head.get("rig") not in RIGS:
        raise ConfigError("protocol.rig", "missing", f"one of {', '.join(RIGS)}", source)
    rig = str(head["rig"])
    sample = parse_sample(head["sample"], source) if "sample" in head else None
    if sorted(completed) != list(range(len(completed))):
        raise ConfigError("steps", sorted(completed), "an interactive run resumes after "
                          "its completed steps 0, 1, ... without a gap", source)
    replay = []
    for index in sorted(completed):
        record = completed[index]
        params = record.get("params") or {}
        replay.append(make_step(record.get("kind"), record.get("name"), params, rig,
                                Where(f"step[{index}]", source), sample))
    return Interactive(rig, str(head.get("name") or "interactive"), sample,
                       replay=tuple(replay))
