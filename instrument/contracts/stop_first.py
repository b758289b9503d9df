"""Stop first, then raise: the one fault path of every driver (design.md, principle 6).

A driver wraps each call that talks to its instrument in :func:`stop_on_fault`. Whatever
escapes the call -- a typed error, a bug, or Ctrl-C (KeyboardInterrupt) -- first triggers the
driver's stop, and only then propagates. A stop that fails itself is logged and noted on the
original exception; it never replaces it, because the original says what went wrong.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from typing import Concatenate, ParamSpec, Protocol, TypeVar

log = logging.getLogger(__name__)

P = ParamSpec("P")
R = TypeVar("R")

_DONE_ATTR = "_gelrig_stops_sent"


@contextmanager
def stop_on_fault(
    stop: Callable[[], object],
    *,
    needed: Callable[[], bool] | None = None,
    spare: tuple[type[BaseException], ...] = (),
    what: str = "instrument",
) -> Iterator[None]:
    """On any exception in the block, call ``stop`` (if ``needed()``), then re-raise it.

    ``needed`` says whether there is anything to stop (e.g. the stage may be moving); None
    means always. Exceptions of the ``spare`` types propagate without a stop (for reports that
    leave the instrument in a sound state). Nested guards with the same ``stop`` call it once
    per exception. ``what`` names the instrument in the log.
    """
    try:
        yield
    except BaseException as exc:
        if not isinstance(exc, spare) and (needed is None or needed()):
            _stop_once(exc, stop, what)
        raise


def _stop_once(exc: BaseException, stop: Callable[[], object], what: str) -> None:
    done: list[Callable[[], object]] = exc.__dict__.setdefault(_DONE_ATTR, [])
    if stop in done:
        return
    done.append(stop)
    try:
        stop()
    except BaseException as failure:  # a second Ctrl-C included: the original still propagates
        log.error("%s: the stop after %s failed: %s: %s", what, type(exc).__name__,
                  type(failure).__name__, failure, exc_info=failure)
        exc.add_note(f"{what}: the stop after this error failed: "
                     f"{type(failure).__name__}: {failure}")


class Guarded(Protocol):
    """A driver whose calls run inside its fault guard."""

    def _guard(self) -> AbstractContextManager[object]: ...


S = TypeVar("S", bound=Guarded)


def guarded(method: Callable[Concatenate[S, P], R]) -> Callable[Concatenate[S, P], R]:
    """Run a driver method inside ``self._guard()`` (built on :func:`stop_on_fault`)."""

    @functools.wraps(method)
    def wrapper(self: S, *args: P.args, **kwargs: P.kwargs) -> R:
        with self._guard():
            return method(self, *args, **kwargs)

    return wrapper


__all__ = ["Guarded", "guarded", "stop_on_fault"]
