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

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, TypeVar

from instrument.clock import Clock
from instrument.rheometer import Rheometer
from instrument.stage import Stage

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


@dataclass
class AxisState:
    """What is known of one moving instrument after the safe stop.

    ``stopped`` is True only when read back as not moving after the stop; ``position`` (m) is
    the read-back position (the plate's, or the gap) or None; ``safe_action`` says what was
    done to the sample and ``safe_ok`` whether it was read back done.
    """

    instrument: str
    quantity: str  # what position means: "plate" or "gap"
    stop_sent: bool = False
    stopped: bool = False
    position: float | None = None
    safe_action: str = ""
    safe_ok: bool | None = None
    errors: list[str] = field(default_factory=list)

    def describe(self) -> str:
        """This instrument's share of the final line."""
        if not self.stopped:
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
            head = "motion stopped (verified)"
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


def stop_stage(
    stage: Stage,
    clock: Clock,
    retract: float,
    first_touch: float | None,
    speed: float,
    acceleration: float,
    budget: float = 15.0,
) -> AxisState:
    """Stop the stage, read it back, then retract the plate ``retract`` m away from first touch
    (or from where it is, if first touch is unknown); ``retract`` 0 only stops."""
    deadline = _Deadline(budget)
    axis = AxisState("stage", "plate")
    _call(axis, deadline, lambda: stage.stop(immediate=True), "stop")
    axis.stop_sent = True  # sent; whether it arrived is what the read-back tells
    if _settle(axis, deadline, clock, stage.is_moving):
        axis.position = _call(axis, deadline, stage.position, "position")
    if not axis.stopped or axis.position is None or retract <= 0:
        return axis
    here = axis.position
    base = first_touch if first_touch is not None else here
    # the driver's software travel limit, if it tells (the contract does not require it)
    lowest = float(getattr(getattr(stage, "config", None), "min_position_m", 0.0))
    target = max(min(here, base - retract), lowest)
    if here - target <= 1e-7:
        axis.safe_action, axis.safe_ok = f"plate clear at {here * 1e3:.3f} mm", True
        return axis
    axis.safe_action = f"plate retracted to {target * 1e3:.3f} mm"
    travel_time = (here - target) / speed + 2 * speed / acceleration + 2.0
    errors_before = len(axis.errors)
    _call(axis, deadline, lambda: stage.set_velocity(speed, acceleration), "set velocity")
    _call(axis, deadline, lambda: stage.move_to(target, wait=False), "retract")
    _call(axis, deadline, lambda: stage.wait_until_stopped(travel_time), "retract wait",
          cap=budget)
    moving = _call(axis, deadline, stage.is_moving, "status")
    position = _call(axis, deadline, stage.position, "position")
    if moving is None or position is None:
        axis.safe_ok = False
        return axis
    axis.position = position
    axis.stopped = not moving
    axis.safe_ok = (len(axis.errors) == errors_before and not moving
                    and abs(position - target) < 20e-6)
    if axis.safe_ok:
        axis.safe_action = f"plate retracted to {position * 1e3:.3f} mm"
    if moving:  # the retract did not end: stop it rather than leave it going
        _call(axis, deadline, lambda: stage.stop(immediate=True), "stop after retract")
    return axis


def stop_rheometer(rheo: Rheometer, clock: Clock, lift: float, budget: float = 15.0
                   ) -> AxisState:
    """Stop the arm, read it back, then lift it by ``lift`` m (0: only stop)."""
    deadline = _Deadline(budget)
    axis = AxisState("rheometer", "gap")
    _call(axis, deadline, rheo.stop, "stop")
    axis.stop_sent = True
    if _settle(axis, deadline, clock, lambda: rheo.status().busy):
        axis.position = _call(axis, deadline, rheo.gap, "gap")
    if not axis.stopped or axis.position is None or lift <= 0:
        return axis
    status = _call(axis, deadline, rheo.status, "status")
    if status is None or not status.gap_referenced:
        return axis  # a gap move needs a referenced gap: stopping is all that is safe
    target = min(axis.position + lift, rheo.config.gap_max)
    if target - axis.position <= 1e-7:
        return axis
    axis.safe_action = f"arm lifted to gap {target * 1e3:.3f} mm"
    errors_before = len(axis.errors)
    _call(axis, deadline, lambda: rheo.set_gap(target, wait=True), "lift", cap=budget)
    status = _call(axis, deadline, rheo.status, "status")
    gap = _call(axis, deadline, rheo.gap, "gap")
    if status is None or gap is None:
        axis.safe_ok = False
        return axis
    axis.position = gap
    axis.stopped = not status.busy
    axis.safe_ok = len(axis.errors) == errors_before and abs(gap - target) < 20e-6
    if axis.safe_ok:
        axis.safe_action = f"arm lifted to gap {gap * 1e3:.3f} mm"
    return axis


def _settle(axis: AxisState, deadline: _Deadline, clock: Clock,
            moving: Callable[[], bool], settle: float = 2.0) -> bool:
    """Read back until not moving (an immediate stop ramps down briefly), for at most
    ``settle`` s of clock time; sets ``axis.stopped``. False if unreachable."""
    start = clock.now()
    while True:
        busy = _call(axis, deadline, moving, "status")
        if busy is None:
            return False
        if not busy:
            axis.stopped = True
            return True
        if clock.now() - start > settle or deadline.left() <= 0:
            return True
        clock.sleep(0.05)
