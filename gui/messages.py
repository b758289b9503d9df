"""Errors in the scientist's words, each with the next action; the wire detail is for the log.

One small table from typed errors (the drivers' error classes and, for instrument error
replies, the instrument and its code) to what a person at the rig reads. What is not in the
table keeps its own message, which the drivers already write for people (LimitError,
ConfigError, the DAQ's driver and device messages).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from gelrig.instrument.contracts.loadcell import AcquisitionOverflowError, ForceOverRangeError
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    FramingError,
    GelrigError,
    InstrumentTimeout,
    InterlockTripped,
)
from gelrig.protocols.rig import NotHomed

#: Instrument names as the drivers begin their messages.
INSTRUMENTS = {"MCR 501": "rheometer", "KDC101": "stage controller",
               "USB-6001": "force DAQ (USB-6001)"}

#: (instrument, code) of an error reply -> what to tell the user (MCR 501 codes: ADR 0020).
REPLIES: dict[tuple[str, int], str] = {
    ("MCR 501", 12): "Reference the gap first: Manual -> Reference gap",
    ("MCR 501", 13): "The rheometer refused the value as out of its range: enter a value "
                     "within the rig file's limits",
    ("MCR 501", 11): "The rheometer refused the value: check the entry and try again",
    ("MCR 501", 10): "The rheometer did not recognise a command: its command table needs "
                     "confirming (docs/decisions/0020); tell whoever maintains gelrig",
    ("MCR 501", 31): "The rheometer stopped itself: normal force overload. Raise the gap "
                     "(Manual -> Set gap) to unload the sample",
    ("MCR 501", 32): "The rheometer stopped itself: torque over range. Stop the rotation and "
                     "raise the gap before going on",
}


@dataclass(frozen=True)
class UserMessage:
    """``text`` for the dialog (what happened and what to do), ``detail`` for the log."""

    text: str
    detail: str


def instrument_of(exc: BaseException) -> str | None:
    """The instrument an error's message names (the drivers begin their messages so)."""
    text = str(exc)
    return next((name for name in INSTRUMENTS if text.startswith(name)), None)


def explain(exc: BaseException) -> UserMessage:
    """What to tell the user about ``exc``, and the wire detail for the log pane."""
    detail = f"{type(exc).__name__}: {exc}"
    return UserMessage(_text(exc), detail)


def explain_fault(kind: str, message: str) -> UserMessage:
    """:func:`explain` for a run's :class:`~gelrig.protocols.events.Fault`, which carries the
    error's
    type name and message (not the error): the typed error is rebuilt from them, the code of an
    error reply read back from its message. A kind that names no known error (the watchdog's)
    keeps its message, which its sender writes for people."""
    cls = _error_classes().get(kind)
    exc: BaseException | None = None
    if cls is not None and issubclass(cls, DeviceErrorReply):
        exc = cls(message, _reply_code(message))
    elif cls is not None:
        try:
            exc = cls(message)
        except TypeError:  # a constructor with other fields (ConfigError): its message stands
            exc = None
    detail = f"{kind}: {message}"
    if exc is None:
        return UserMessage(message or kind, detail)
    return UserMessage(_text(exc), detail)


def in_words(reason: str) -> str:
    """A run's end reason as people read it: ``"Kind: message"`` of a known error type goes
    through :func:`explain_fault`; any other reason (written for people) stays as it is."""
    kind, sep, message = reason.partition(": ")
    if not sep or kind not in _error_classes():
        return reason
    return explain_fault(kind, message).text


#: How the drivers write an error reply's code in its message (MCR 501, KDC101, DAQmx).
_CODE = re.compile(r"(?:error |\(code |DAQmx )(-?\d+)")


def _reply_code(message: str) -> int | None:
    found = _CODE.search(message)
    return int(found.group(1)) if found else None


def _error_classes() -> dict[str, type[BaseException]]:
    """The project's error classes (and OSError's) by name, found where they are defined."""
    out: dict[str, type[BaseException]] = {}
    todo: list[type[BaseException]] = [GelrigError, OSError]
    while todo:
        cls = todo.pop()
        out.setdefault(cls.__name__, cls)
        todo.extend(cls.__subclasses__())
    return out


def _text(exc: BaseException) -> str:
    source = instrument_of(exc)
    who = INSTRUMENTS.get(source or "", "instrument")
    if isinstance(exc, NotHomed):
        return "Home the stage first: Manual -> Home (nothing moved)"
    if isinstance(exc, InterlockTripped):
        return (f"An interlock stopped the motion ({exc}). Unload the sample, then "
                "Acknowledge on the interlock banner")
    if isinstance(exc, DeviceErrorReply) and source is not None and exc.code is not None:
        known = REPLIES.get((source, exc.code))
        if known is not None:
            return known
    if isinstance(exc, AcquisitionOverflowError):
        return ("The force acquisition fell behind and lost samples: try again; if it "
                "repeats, Disconnect and Connect the rig")
    if isinstance(exc, ForceOverRangeError):
        return ("The load cell is over its range: motion was stopped. Unload the sample "
                "(move the plate away) before going on")
    if isinstance(exc, InstrumentTimeout):
        return (f"The {who} did not answer in time: check its power and cable, then "
                "Disconnect and Connect the rig")
    if isinstance(exc, Disconnected):
        return (f"The link to the {who} was lost: check its power and cable, then "
                "Disconnect and Connect the rig")
    if isinstance(exc, FramingError):
        return (f"The {who} answered with garbled bytes: check the cable and the port in "
                "the rig file, then Disconnect and Connect the rig")
    if isinstance(exc, DeviceErrorReply):
        return (f"The {who} refused the command: {_short(exc)}. Check the entry; if it "
                "repeats, Disconnect and Connect the rig")
    if isinstance(exc, GelrigError):
        return str(exc)  # written for people where it is raised (limits, rig files)
    if isinstance(exc, ConnectionRefusedError):
        return ("Nothing answers at the instrument's address: is the instrument (or its "
                "simulator) switched on and the address in the rig file right?")
    if isinstance(exc, OSError):
        return f"The computer could not reach the instrument ({exc}): check cables and address"
    return f"Unexpected error ({type(exc).__name__}: {exc}); the log has the details"


def _short(exc: BaseException) -> str:
    """An error reply's text without the instrument's prefix."""
    text = str(exc)
    source = instrument_of(exc)
    if source is not None:
        text = text[len(source):].lstrip(" :")
    return text
