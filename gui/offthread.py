"""Work off the GUI thread whose worker never holds a Qt object.

A Python thread that drops the last reference to a Qt object destroys it on that thread:
``~QObject`` takes Qt's signal lock, then waits for the GIL to ask Python about overrides,
while the GUI thread, holding the GIL, waits for that lock. Both wait for ever (seen: a run
window closed while its analysis thread was still running hung the GUI in ``MainWindow``'s
constructor). So a worker here holds only its plain work and a token; the callback that
takes the result stays on the GUI thread, in a table keyed by the token, and the result
crosses on a relay that lives for the whole process and so is never the last reference.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from typing import Any

import shiboken6
from PySide6.QtCore import QObject, Qt, Signal

Callback = Callable[[Any], None]


class _Relay(QObject):
    """Tells the GUI thread, from any thread, that the result for a token is in."""

    delivered = Signal(int)


_relay: _Relay | None = None
_waiting: dict[int, tuple[Callback, QObject | None]] = {}
_results: dict[int, object] = {}
_lock = threading.Lock()
_tokens = itertools.count(1)


def ready() -> None:
    """On the GUI thread, before a worker may :func:`send`: make the relay if need be."""
    _the_relay()


def _the_relay() -> _Relay:
    global _relay
    if _relay is None:
        if threading.current_thread() is not threading.main_thread():
            raise RuntimeError("the result relay must be made on the GUI thread")
        _relay = _Relay()
        _relay.delivered.connect(_dispatch, Qt.ConnectionType.QueuedConnection)
    return _relay


def expect(callback: Callback, owner: QObject | None = None) -> int:
    """On the GUI thread: keep ``callback`` for a result to come; the token to send it by.
    The result is dropped if ``owner`` (by default the object a bound ``callback`` belongs
    to) has been deleted by then."""
    _the_relay()
    if owner is None and isinstance(getattr(callback, "__self__", None), QObject):
        owner = callback.__self__  # type: ignore[attr-defined]
    with _lock:
        token = next(_tokens)
        _waiting[token] = (callback, owner)
    return token


def send(token: int, box: list[object]) -> None:
    """From any thread: hand the one value in ``box`` to the callback kept under ``token``.
    The value is taken out of ``box`` before the GUI thread is told, so the sender holds
    no reference to it that could outlive the GUI thread's."""
    relay = _relay
    if relay is None:
        raise RuntimeError("send() before expect(): no relay to carry the result")
    with _lock:
        _results[token] = box.pop()
    relay.delivered.emit(token)


def forget(token: int) -> None:
    """On the GUI thread: a result that comes for ``token`` is dropped."""
    with _lock:
        _waiting.pop(token, None)


def _dispatch(token: int) -> None:
    with _lock:
        callback, owner = _waiting.pop(token, (None, None))
        value = _results.pop(token, None)
    if callback is None:
        return
    if owner is not None and not shiboken6.isValid(owner):
        return  # its window was closed and deleted while the work ran
    callback(value)


def qt_objects_held(fn: Callable[..., Any]) -> list[str]:
    """The Qt objects ``fn`` holds directly (its bound ``self``, its closure's cells, its
    default values, and the objects of bound methods among them): what a worker thread
    must not be given."""
    held: list[object] = []
    bound = getattr(fn, "__self__", None)
    if bound is not None:
        held.append(bound)
        fn = getattr(fn, "__func__", fn)
    for cell in getattr(fn, "__closure__", None) or ():
        try:
            held.append(cell.cell_contents)
        except ValueError:  # a cell not filled yet
            continue
    held.extend(getattr(fn, "__defaults__", None) or ())
    held.extend(getattr(obj, "__self__", None) for obj in list(held))  # bound methods
    return [type(obj).__name__ for obj in held if isinstance(obj, QObject)]


def refuse_qt(work: Callable[..., Any]) -> None:
    """Raise ``TypeError`` naming the Qt objects ``work`` holds directly: work meant for a
    worker thread must hold none."""
    held = qt_objects_held(work)
    if held:
        raise TypeError(f"work for a thread holds Qt objects ({', '.join(held)}): "
                        "give it plain values and take the result on the GUI thread")


def start(work: Callable[[], object], done: Callback, name: str) -> int:
    """Run ``work`` on a new daemon thread; ``done(result)`` on the GUI thread, where the
    result is what ``work`` returned or the exception it raised. ``work`` must hold no Qt
    object (checked: a ``TypeError`` names what it holds). Returns the token, for
    :func:`forget`."""
    refuse_qt(work)
    token = expect(done)

    def run() -> None:
        box: list[object] = []
        try:
            box.append(work())
        except Exception as exc:  # handed to done(), which says it
            box.append(exc)
        send(token, box)

    threading.Thread(target=run, name=name, daemon=True).start()
    return token
