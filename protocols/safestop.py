"""The verified safe end state of a run (ADR 0070).

On any fault, abort or interlock trip: stop every motion, read back what each moving
instrument does and where it is, then put the sample in its safe state where the rig file asks
for it (retract the plate, lift the arm). Nothing is claimed that was not read back: the
result, a :class:`SafeState`, says per instrument what was sent and what was verified, and
gives the one line people see. Every instrument call here runs with a bounded wall-time wait,
on a helper thread if need be, so a frozen instrument cannot hang the way out; nothing here
raises.
"""

from __future__ import annotations

import functools
import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, TypeVar

from gelrig.instrument.contracts.rheometer import Rheometer
from gelrig.instrument.contracts.stage import Stage
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import (
    Disconnected,
    FramingError,
    InstrumentError,
    InstrumentTimeout,
)

log = logging.getLogger(__name__)

T = TypeVar("T")

#: Wall-time bound (s) of one instrument call on the way out (a stop, a status, a position).
CALL_TIMEOUT = 3.0


class Unanswered(Exception):
    """An instrument call did not return within its bound (the instrument may be frozen)."""


def bounded(call: Callable[[], T], timeout: float, what: str) -> T:
    """``call()`` on a helper thread, waiting at most ``timeout`` s of wall time.

    Returns its value or raises its exception; raises :class:`Unanswered` if it has not
    returned in time (the helper thread is left to finish or hang on its own: a daemon).
    """
    box: queue.Queue[tuple[bool, Any]] = queue.Queue(maxsize=1)

    def target() -> None:
        try:
            box.put((True, call()))
        except BaseException as exc:  # handed to the caller
            box.put((False, exc))

    threading.Thread(target=target, name=f"safe-stop {what}", daemon=True).start()
    try:
        ok, value = box.get(timeout=max(timeout, 0.0))
    except queue.Empty:
        raise Unanswered(f"{what}: no answer within {timeout:g} s") from None
    if ok:
        return value
    raise value


def _why(exc: BaseException) -> str:
    if isinstance(exc, Unanswered):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


def _link_lost(exc: BaseException) -> bool:
    """The link itself is gone (a write failed, the peer closed): a new one may reach the
    instrument."""
    return isinstance(exc, Disconnected)


@dataclass
class AxisState:
    """What is known of one moving instrument after the safe stop.

    ``stop_sent`` is True only when a stop was written on a link that was up (its answer may
    not have come); ``reconnected`` when the link was lost and the stop went out on a new
    one. ``stopped`` is True only when read back as not moving after the stop; ``position``
    (m) is the read-back position (the plate's, or the gap) or None; ``force`` (N) the load
    read back after the safe action when it was needed to end it (first touch or touch gap
    unknown); ``safe_action`` says what was done to the sample and ``safe_ok`` whether it
    was read back done.
    """

    instrument: str
    quantity: str  # what position means: "plate" or "gap"
    stop_sent: bool = False
    reconnected: bool = False
    stopped: bool = False
    position: float | None = None
    force: float | None = None
    safe_action: str = ""
    safe_ok: bool | None = None
    errors: list[str] = field(default_factory=list)

    def describe(self) -> str:
        """This instrument's share of the final line."""
        if not self.stopped:
            if not self.stop_sent:
                return (f"STOP NOT SENT: {self.instrument} link lost and not reopened "
                        "- check the rig")
            if self.errors:
                return (f"STOP SENT, NOT CONFIRMED: {self.instrument} unreachable "
                        "- check the rig")
            return f"STILL MOVING after the stop: {self.instrument} - check the rig"
        text = f"{self.instrument} stopped"
        if self.safe_action:
            text = self.safe_action if self.safe_ok else (
                f"{text}; {self.safe_action.upper()} NOT CONFIRMED - check the rig")
        elif self.position is not None:
            text += f" at {self.quantity} {self.position * 1e3:.3f} mm"
        return text

    @property
    def link_note(self) -> str:
        """How the stop went out when the link had to be reopened, else ''."""
        return f"{self.instrument} stop sent on a new link" if self.reconnected else ""


@dataclass
class SafeState:
    """What the safe stop verified, per moving instrument, and why it ran."""

    reason: str
    axes: list[AxisState] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def verified(self) -> bool:
        """Every motion read back as stopped and every safe action read back as done."""
        return bool(self.axes) and all(a.stopped and a.safe_ok is not False for a in self.axes)

    def line(self) -> str:
        """The one line people see: only what is known."""
        parts = [a.describe() for a in self.axes]
        if all(a.stopped for a in self.axes) and self.axes:
            notes = [a.link_note for a in self.axes if a.link_note]
            head = "motion stopped (verified" + "".join(f"; {n}" for n in notes) + ")"
            tail = [a.safe_action if a.safe_ok else a.describe() for a in self.axes
                    if a.safe_action]
            return "; ".join([head, *tail])
        return "; ".join(parts) or "STOP NOT SENT: no instrument - check the rig"

    def as_dict(self) -> dict[str, Any]:
        """run.json's ``safe_state``: the line, whether verified, and the facts per axis."""
        return {"line": self.line(), "verified": self.verified, "reason": self.reason,
                "wall_s": round(self.wall_s, 3),
                "instruments": {a.instrument: {k: v for k, v in asdict(a).items()
                                               if k != "instrument"} for a in self.axes}}


class _Deadline:
    """Wall-time budget of the whole safe stop; each call gets what is left, at most
    ``CALL_TIMEOUT``."""

    def __init__(self, seconds: float):
        self.end = time.monotonic() + seconds

    def left(self, cap: float = CALL_TIMEOUT) -> float:
        return max(0.0, min(cap, self.end - time.monotonic()))


def _call(axis: AxisState, deadline: _Deadline, call: Callable[[], T], what: str,
          cap: float = CALL_TIMEOUT) -> T | None:
    """``call()`` bounded; a failure is noted on ``axis`` and logged, and gives None."""
    try:
        return bounded(call, deadline.left(cap), f"{axis.instrument} {what}")
    except BaseException as exc:  # the safe stop never raises
        axis.errors.append(f"{what}: {_why(exc)}")
        log.error("safe stop: %s %s failed: %s", axis.instrument, what, _why(exc),
                  exc_info=not isinstance(exc, Unanswered))
        return None


#: Attempts to open a new link when the link to a moving instrument is lost (each bounded by
#: what is left of the safe stop's budget), and the wall seconds between them.
RECONNECT_ATTEMPTS = 3
RECONNECT_PAUSE = 0.3

#: Errors that say the instrument did not answer on a link that is up: a stop written there
#: went out; reading back now would only wait again.
_SILENT = (Unanswered, InstrumentTimeout, FramingError)


def _reopen(axis: AxisState, deadline: _Deadline, instrument: object) -> bool:
    """Close the lost link and open a new one to the same address (the driver's
    ``reopen()``), at most :data:`RECONNECT_ATTEMPTS` times within the budget."""
    reopen = getattr(instrument, "reopen", None)
    if not callable(reopen):
        return False
    for attempt in range(1, RECONNECT_ATTEMPTS + 1):
        if deadline.left() <= 0:
            break
        try:
            bounded(reopen, deadline.left(), f"{axis.instrument} reopen")
        except BaseException as exc:  # the safe stop never raises
            axis.errors.append(f"reopen (attempt {attempt}): {_why(exc)}")
            log.error("safe stop: reopening the %s link failed: %s", axis.instrument, _why(exc))
            time.sleep(min(RECONNECT_PAUSE, deadline.left()))
            continue
        log.warning("safe stop: %s link lost; a new link is open (attempt %d)",
                    axis.instrument, attempt)
        return True
    return False


def _send_stop(axis: AxisState, deadline: _Deadline, stop: Callable[[], object],
               fresh: bool) -> BaseException | None:
    """Send the stop (bounded); notes whether it went out; returns its failure or None."""
    what = "stop on a new link" if fresh else "stop"
    try:
        bounded(stop, deadline.left(), f"{axis.instrument} {what}")
    except BaseException as exc:  # the safe stop never raises
        axis.errors.append(f"{what}: {_why(exc)}")
        log.error("safe stop: %s %s failed: %s", axis.instrument, what, _why(exc),
                  exc_info=not isinstance(exc, Unanswered | InstrumentError))
        if not _link_lost(exc):  # written on a working link; only its answer is missing
            axis.stop_sent, axis.reconnected = True, fresh
        return exc
    axis.stop_sent, axis.reconnected = True, fresh
    return None


def _stop_and_verify(axis: AxisState, deadline: _Deadline, clock: Clock, instrument: object,
                     stop: Callable[[], object], moving: Callable[[], bool]) -> bool:
    """Send the stop and read back until not moving; a lost link (the stop or the read-back
    failing as Disconnected) is reopened once and both are done again on the new link.
    True when the instrument answered the read-back (``axis.stopped`` says what it said)."""
    fresh = False
    while True:
        failure = _send_stop(axis, deadline, stop, fresh)
        if isinstance(failure, _SILENT):
            return False  # silent: the stop went out; the pending safe stop reads back later
        if failure is not None and _link_lost(failure) and not fresh \
                and _reopen(axis, deadline, instrument):
            fresh = True
            continue
        read = _settle(axis, deadline, clock, moving)
        if read is not None and _link_lost(read) and not fresh \
                and _reopen(axis, deadline, instrument):
            fresh = True
            continue
        return read is None


def stop_stage(
    stage: Stage,
    clock: Clock,
    retract: float,
    first_touch: float | None,
    speed: float,
    acceleration: float,
    budget: float = 15.0,
    force: Callable[[], float] | None = None,
    loaded: float = math.inf,
) -> AxisState:
    """Stop the stage, read it back, then retract the plate ``retract`` m away from first touch;
    ``retract`` 0 only stops. With first touch unknown the plate goes back ``retract`` at a
    time from where it is until ``force()`` (N, the load read now) is at most ``loaded``, or
    to the end of travel (all the way when ``force`` is None: nothing can tell it is clear)."""
    deadline = _Deadline(budget)
    axis = AxisState("stage", "plate")
    if _stop_and_verify(axis, deadline, clock, stage, lambda: stage.stop(immediate=True),
                        stage.is_moving):
        axis.position = _call(axis, deadline, stage.position, "position")
    if not axis.stopped or axis.position is None or retract <= 0:
        return axis
    here = axis.position
    # the driver's software travel limit, if it tells (the contract does not require it)
    lowest = float(getattr(getattr(stage, "config", None), "min_position_m", 0.0))
    by_force = first_touch is None
    if by_force and force is None:
        retract = math.inf  # where the sphere is is not known, nor what it feels: all the way
    base = first_touch if first_touch is not None else here
    target = max(min(here, base - retract), lowest)
    if here - target <= 1e-7 and not by_force:
        axis.safe_action, axis.safe_ok = f"plate clear at {here * 1e3:.3f} mm", True
        return axis
    errors_before = len(axis.errors)
    _call(axis, deadline, lambda: stage.set_velocity(speed, acceleration), "set velocity")
    unread = by_force and force is None  # the load cannot be told: the end of travel it is
    while True:
        if here - target > 1e-7 and not _retract_to(axis, deadline, stage, here, target, speed,
                                                      acceleration, budget):
            return axis
        here = axis.position if axis.position is not None else here
        if not by_force or force is None:
            break
        axis.force = _call(axis, deadline, force, "force")
        if axis.force is None:  # unreadable now: all the way back
            force, unread, target = None, True, lowest
            continue
        if axis.force <= loaded or here <= lowest + 1e-7 or deadline.left() <= 0:
            break
        target = max(here - retract, lowest)
    at_end = here <= lowest + 1e-7
    cleared = not by_force or (axis.force <= loaded if axis.force is not None else at_end)
    axis.safe_ok = axis.stopped and cleared and (
        len(axis.errors) == errors_before or (unread and at_end))
    axis.safe_action = f"plate retracted to {here * 1e3:.3f} mm"
    if axis.force is not None:
        axis.safe_action += f", {axis.force * 1e3:.3g} mN read back"
    elif unread:
        axis.safe_action += " (end of travel: the load could not be read)"
    return axis


def _retract_to(axis: AxisState, deadline: _Deadline, stage: Stage, here: float,
                target: float, speed: float, acceleration: float, budget: float) -> bool:
    """Move the plate back to ``target`` and read it back; False if it cannot be told there."""
    travel_time = (here - target) / speed + 2 * speed / acceleration + 2.0
    errors_before = len(axis.errors)
    _call(axis, deadline, lambda: stage.move_to(target, wait=False), "retract")
    _call(axis, deadline, lambda: stage.wait_until_stopped(travel_time), "retract wait",
          cap=budget)
    moving = _call(axis, deadline, stage.is_moving, "status")
    position = _call(axis, deadline, stage.position, "position")
    if moving:  # the retract did not end: stop it rather than leave it going
        _call(axis, deadline, lambda: stage.stop(immediate=True), "stop after retract")
    if moving is None or position is None:
        axis.safe_action = f"plate retracted to {target * 1e3:.3f} mm"
        axis.safe_ok = False
        return False
    axis.position = position
    axis.stopped = not moving
    if len(axis.errors) > errors_before or moving or abs(position - target) >= 20e-6:
        axis.safe_action = f"plate retracted to {target * 1e3:.3f} mm"
        axis.safe_ok = False
        return False
    return True


def stop_rheometer(rheo: Rheometer, clock: Clock, lift: float, budget: float = 15.0,
                   normal_force: Callable[[], float] | None = None,
                   loaded: float = math.inf) -> AxisState:
    """Stop the arm, read it back, then lift it by ``lift`` m (0: only stop). With the touch
    gap unknown (``normal_force`` given) it lifts ``lift`` at a time until ``|normal_force()|``
    (N) is at most ``loaded``, or to the top of the lift."""
    deadline = _Deadline(budget)
    axis = AxisState("rheometer", "gap")
    if _stop_and_verify(axis, deadline, clock, rheo, rheo.stop, lambda: rheo.status().busy):
        axis.position = _call(axis, deadline, rheo.gap, "gap")
    if not axis.stopped or axis.position is None or lift <= 0:
        return axis
    status = _call(axis, deadline, rheo.status, "status")
    if status is None or not status.gap_referenced:
        return axis  # a gap move needs a referenced gap: stopping is all that is safe
    top = rheo.config.gap_max
    here = axis.position
    errors_before = len(axis.errors)
    while True:
        target = min(here + lift, top)
        if target - here > 1e-7:
            axis.safe_action = f"arm lifted to gap {target * 1e3:.3f} mm"
            _call(axis, deadline, functools.partial(rheo.set_gap, target, wait=True), "lift",
                  cap=budget)
            status = _call(axis, deadline, rheo.status, "status")
            gap = _call(axis, deadline, rheo.gap, "gap")
            if status is None or gap is None:
                axis.safe_ok = False
                return axis
            axis.position, axis.stopped = gap, not status.busy
            if len(axis.errors) > errors_before or abs(gap - target) >= 20e-6:
                axis.safe_ok = False
                return axis
            here = gap
        elif normal_force is None:
            return axis  # already at the top: nothing to lift
        if normal_force is None:
            break
        reading = _call(axis, deadline, normal_force, "normal force")
        axis.force = None if reading is None else abs(reading)
        if axis.force is None or axis.force <= loaded or here >= top - 1e-7 \
                or deadline.left() <= 0:
            break
    axis.safe_ok = axis.stopped and len(axis.errors) == errors_before and (
        normal_force is None or (axis.force is not None and axis.force <= loaded))
    axis.safe_action = f"arm lifted to gap {here * 1e3:.3f} mm"
    if axis.force is not None:
        axis.safe_action += f", normal force {axis.force * 1e3:.3g} mN read back"
    return axis


def _settle(axis: AxisState, deadline: _Deadline, clock: Clock,
            moving: Callable[[], bool], settle: float = 2.0) -> BaseException | None:
    """Read back until not moving (an immediate stop ramps down briefly), for at most
    ``settle`` s of clock time; sets ``axis.stopped``. Returns the read-back's failure, or
    None when the instrument answered."""
    start = clock.now()
    while True:
        try:
            busy = bounded(moving, deadline.left(), f"{axis.instrument} status")
        except BaseException as exc:  # the safe stop never raises
            axis.errors.append(f"status: {_why(exc)}")
            log.error("safe stop: %s status failed: %s", axis.instrument, _why(exc))
            return exc
        if not busy:
            axis.stopped = True
            return None
        if clock.now() - start > settle or deadline.left() <= 0:
            return None
        clock.sleep(0.05)
