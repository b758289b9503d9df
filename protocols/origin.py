"""Where in the code a run is: the script's ``file:line`` of an exception, and what the run
thread is doing when it has gone silent (an instrument call, or the script's own code).

Code is sorted by where it lives: gelrig's instrument code (``drivers/``, ``simulators/``),
gelrig's other packages, the standard library and installed packages, and the rest, which is
the user's (a script, a step kind it registers, a notebook).
"""

from __future__ import annotations

import os
import sys
import sysconfig
import threading
import traceback
from collections.abc import Iterable
from functools import cache
from pathlib import Path
from types import FrameType

_ROOT = Path(__file__).resolve().parents[1]
#: gelrig's packages (the top-level folders ``gelrig.*`` links to, and ``gelrig`` itself).
_OWN = tuple(_ROOT / name for name in ("instrument", "drivers", "simulators", "protocols",
                                       "gui", "gelrig"))
#: gelrig's code that talks to an instrument.
_INSTRUMENT = (_ROOT / "drivers", _ROOT / "simulators")


@cache
def _resolved(filename: str) -> Path:
    return Path(filename).resolve()


@cache
def _stdlib() -> Path:
    return Path(sysconfig.get_paths()["stdlib"]).resolve()


def is_users(filename: str) -> bool:
    """The file is the user's: a file (not ``<frozen ...>``, ``<string>`` or a relative
    name of an embedded loader) that is not gelrig's, not the standard library, not an
    installed package."""
    if not os.path.isabs(filename):
        return False
    path = _resolved(filename)
    return not ({"site-packages", "dist-packages"} & set(path.parts)
                or any(path.is_relative_to(p) for p in (*_OWN, _stdlib())))


def is_instrument(filename: str) -> bool:
    """The file is gelrig's instrument code (a driver or a simulator)."""
    path = _resolved(filename)
    return any(path.is_relative_to(p) for p in _INSTRUMENT)


def origin(exc: BaseException) -> str:
    """``file:line`` of the innermost frame of ``exc`` in the user's code (where a script
    went wrong), or ''."""
    found = ""
    for frame in traceback.extract_tb(exc.__traceback__):
        if is_users(frame.filename):
            found = f"{Path(frame.filename).name}:{frame.lineno}"
    return found


def user_site(frame: FrameType | None) -> str:
    """``file:line`` of the innermost frame in the user's code from ``frame`` out to its
    callers (the script line that asked for something), or ''."""
    for f in _frames(frame):
        if is_users(f.f_code.co_filename):
            return f"{Path(f.f_code.co_filename).name}:{f.f_lineno}"
    return ""


def _frames(frame: FrameType | None) -> Iterable[FrameType]:
    """``frame`` and its callers, innermost first."""
    while frame is not None:
        yield frame
        frame = frame.f_back


def stuck_site(frame: FrameType | None) -> tuple[str, str]:
    """What a thread whose innermost frame is ``frame`` is doing: ("instrument", where) in a
    call to an instrument, ("script", ``file:line``) in the user's own code, ("", "") if
    neither can be told.

    An instrument call is a driver or simulator frame on the stack (where: the innermost
    one, ``kdc101/driver.py:212 in _request``), or user code that gelrig called as an
    instrument (a test double, an instrument of the user's). The user's own code is user
    code that the run called as its procedure: the script's function or a step kind's
    ``run`` (where: the innermost user frame)."""
    frames = list(_frames(frame))
    for i, f in enumerate(frames):
        filename = f.f_code.co_filename
        if is_instrument(filename):
            return "instrument", _site(f)
        if is_users(filename):
            caller = next((c for c in frames[i + 1:] if not is_users(c.f_code.co_filename)),
                          None)
            if caller is None or _resolved(caller.f_code.co_filename) in _PROCEDURE_CALLS:
                return "script", f"{Path(filename).name}:{f.f_lineno}"
            return "instrument", _site(f)
    return "", ""


def _site(frame: FrameType) -> str:
    path = _resolved(frame.f_code.co_filename)
    return f"{path.parent.name}/{path.name}:{frame.f_lineno} in {frame.f_code.co_name}"


#: gelrig's files that call the user's procedure code: the script's function
#: (``Script.drive``) and a step kind's ``run`` (``Runner._step``).
_PROCEDURE_CALLS = frozenset({_ROOT / "protocols" / "script.py",
                              _ROOT / "protocols" / "runner.py"})


def thread_site(thread: threading.Thread | None) -> tuple[str, str]:
    """:func:`stuck_site` of ``thread``'s current frame (("", "") if it is not running)."""
    if thread is None or thread.ident is None:
        return "", ""
    return stuck_site(sys._current_frames().get(thread.ident))


def stuck_words(kind: str, where: str) -> str:
    """The words for people: ``stuck in an instrument call (...)``, ``the script's own code
    (x.py:12) has not returned``, or that an instrument may be frozen."""
    if kind == "instrument":
        return f"stuck in an instrument call ({where})"
    if kind == "script":
        return f"the script's own code ({where}) has not returned"
    return "an instrument may be frozen"
