"""Manual motions under the interlocks: a jog, move, home, rotation or gap change is watched
sample by sample exactly as a protocol step watches its motion (ADR 0170).

A guarded motion is a tiny step: a :class:`~gelrig.protocols.context.StepContext` with a private
event stream, the rig's interlocks armed, and the recorders the steps use
(:class:`~gelrig.protocols.steps.acquire.ForceRecorder`,
:class:`~gelrig.protocols.steps.arm.ArmRecorder`),
whose blocks shrink to one sample near a limit. So a manual move into the sphere stops within
one sample of the force crossing its limit, and a Stop (``control.abort``) ends the motion at
the next block. The call blocks until the motion ends; live values go to ``on_values``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import GelrigError, InterlockTripped
from gelrig.protocols.context import StepContext
from gelrig.protocols.control import Aborted, RunControl
from gelrig.protocols.events import Event, EventBus, InterlockTrip, Samples
from gelrig.protocols.rig import CompressionRig, Rig, ShearRig
from gelrig.protocols.safestop import AxisState, SafeState, stop_rheometer, stop_stage

log = logging.getLogger(__name__)

#: Force sample rate (Hz) while a manual compression move is watched (the USB-6001's lowest,
#: the idle readout's too, so the acquisition is not restarted).
MANUAL_RATE = 100.0
#: Stream interval (s) of the rheometer while a manual motion is watched.
ARM_INTERVAL = 0.01
#: Longest a manual motion that ends by itself is watched (s of lab time): a bound, not a plan.
MAX_WATCH = 3600.0

Values = Callable[[dict[str, float]], None]


@dataclass(frozen=True)
class Guarded:
    """How a manual motion ended: ``"done"``, ``"stopped"`` (Stop, or a newer command) or
    ``"tripped"`` (``trip`` holds the event)."""

    what: str
    outcome: str
    reason: str = ""
    trip: InterlockTrip | None = None
    #: a stopped or tripped motion's stop, read back (what a message may claim)
    safe: SafeState | None = None


class _Latest:
    """The bus subscriber that turns sample blocks into live values (position, force...)."""

    def __init__(self, on_values: Values | None):
        self.on_values = on_values
        self.trip: InterlockTrip | None = None

    def __call__(self, event: Event) -> None:
        if isinstance(event, InterlockTrip):
            self.trip = event
        elif isinstance(event, Samples) and self.on_values is not None:
            values = {k: float(v[-1]) for k, v in event.data.items()
                      if len(v) and k in _SHOWN}
            if "force_N" in event.data and len(event.data["force_N"]):
                values["force_N"] = float(np.mean(event.data["force_N"][-10:]))
            values["moving"] = 1.0
            self.on_values(values)


_SHOWN = frozenset({"t_s", "position_m", "force_N", "gap_m", "angle_rad", "theta_m",
                    "torque_Nm", "normal_force_N"})


def block_time(clock: Clock) -> float:
    """Lab time (s) a manual motion reads at a time: one sample (10 ms) in real time, so a
    Stop is seen within one sample period; on a paced simulated clock one sample of wall
    time (10 ms of wall time: more samples at 10x, the default 0.1 s as fast as possible),
    so a fast pace does not flood the rig thread with calls."""
    rate = getattr(clock, "rate", 1.0)
    if not math.isfinite(rate):
        return 0.1
    return min(0.1, max(1.0, rate) / MANUAL_RATE)


def guarded(rig: Rig, what: str, start: Callable[[], object], control: RunControl,
            on_values: Values | None = None, toward: bool = True,
            until_stopped: bool = True) -> Guarded:
    """Run ``start()`` (a non-blocking motion command) and watch it under the rig's
    interlocks until it ends, a Stop (``control.abort``) or a trip; motion is stopped on the
    way out of a stop or a trip. ``toward``: the move loads the sample (a move away from it,
    the plate back or the arm up, only unloads, so the limits do not refuse it: ADR 0170).
    ``until_stopped`` False: the motion does not end by itself (a rotation); watch until
    stopped. Errors of the instruments propagate (motion stopped first)."""
    bus = EventBus()
    latest = _Latest(on_values)
    bus.subscribe(latest)
    try:
        if isinstance(rig, CompressionRig):
            _watch_stage(StepContext(rig, bus, control, -1), rig, start, toward)
        else:
            _watch_arm(StepContext(rig, bus, control, -1), rig, start, toward, until_stopped)
    except InterlockTripped as exc:
        rig.stop_all()  # the context stopped it already: once more does no harm
        return Guarded(what, "tripped", str(exc), latest.trip,
                       verified_stop(rig, f"{what}: {exc}"))
    except Aborted as exc:
        rig.stop_all()
        reason = str(exc) or "stop pressed"
        return Guarded(what, "stopped", reason, safe=verified_stop(rig, f"{what}: {reason}"))
    except BaseException:
        rig.stop_all()
        raise
    return Guarded(what, "done")


def _watch_stage(ctx: StepContext[CompressionRig], rig: CompressionRig,
                 start: Callable[[], object], toward: bool) -> None:
    from gelrig.protocols.steps.acquire import ForceRecorder  # steps import this package's modules

    ctx.interlocks = rig.interlocks(overlap=rig.first_touch is not None) if toward else ()
    rig.end_monitoring()  # drop the idle readout's unread samples: watch from now on
    rec = ForceRecorder(ctx, MANUAL_RATE, keep=False,
                        first_touch=rig.first_touch if rig.first_touch is not None
                        else math.nan, block_time=block_time(ctx.clock))
    rec.start()
    rig.monitoring = True  # the acquisition runs at the readout's rate: it reads on after
    start()
    end = ctx.clock.now() + MAX_WATCH
    rec.read()  # the first samples of the motion, before asking whether it is over
    while rig.stage.is_moving() and ctx.clock.now() < end:
        rec.read()
    rec.read()


def _watch_arm(ctx: StepContext[ShearRig], rig: ShearRig, start: Callable[[], object],
               toward: bool, until_stopped: bool) -> None:
    from gelrig.protocols.steps.arm import ArmRecorder

    ctx.interlocks = rig.interlocks() if toward else ()
    rec = ArmRecorder(ctx, ARM_INTERVAL, read_period=block_time(ctx.clock))
    try:
        start()
        end = ctx.clock.now() + MAX_WATCH
        while ctx.clock.now() < end:
            ctx.clock.sleep(rec.next_read())
            rec.poll()
            if until_stopped and not rig.rheometer.status().busy:
                break
    finally:
        try:
            rig.rheometer.stop_stream()
        except Exception:
            log.exception("stopping the rheometer's stream failed")



def verified_stop(rig: Rig, reason: str, budget: float = 5.0) -> SafeState:
    """Stop every axis and read back that it stopped, without moving the sample (a manual
    trip or Stop leaves it where it is: the banner offers Unload). Never raises."""
    if isinstance(rig, CompressionRig):
        return rig._stopped(reason, lambda: stop_stage(
            rig.stage, rig.clock, 0.0, rig.first_touch, rig.limits.fast_speed,
            rig.limits.acceleration, budget))
    return rig._stopped(reason, lambda: stop_rheometer(rig.rheometer, rig.clock, 0.0, budget))


class _Loaded(AxisState):
    """The load read back after a safe stop, the sample still loaded: not safe."""

    def describe(self) -> str:
        return f"SAMPLE STILL LOADED: {self.safe_action} - unload it"


def still_loaded(rig: Rig, safe: SafeState, read: Callable[[], Mapping[str, float]]
                 ) -> SafeState:
    """``safe`` as it is when the load read back after it is below the loaded level (the
    rig's :meth:`load_state`); otherwise not verified, its line saying what is still loaded
    (or that the load could not be read). "Safe" means both: the stop and the load."""
    try:
        why = rig.load_state(read())
    except Exception as exc:
        why = f"the load could not be read ({type(exc).__name__}: {exc})"
    if why is None:
        return safe
    axis = _Loaded("load", "load", stop_sent=True, stopped=True, safe_action=why, safe_ok=False)
    return SafeState(safe.reason, [*safe.axes, axis], safe.wall_s)


#: The fastest manual move toward the sample while first touch is unknown (m/s): the contact
#: search's default probe speed, at which the force interlock catches a touch early.
APPROACH_SPEED = 0.3e-3


class FirstTouchUnknown(GelrigError):
    """A plate move toward the sample before a contact search, not confirmed: where the
    sphere is is not known, so the overlap limit is not armed; nothing moved."""


def approach_speed(rig: CompressionRig, speed: float, target: float | None = None,
                   by: float | None = None, confirmed: bool = False) -> float:
    """The speed (m/s) a manual plate move may use. Toward the sample with first touch
    unknown (no contact search yet) it is refused (:class:`FirstTouchUnknown`) unless
    ``confirmed``, and then at most :data:`APPROACH_SPEED`; otherwise ``speed``."""
    if rig.first_touch is not None or not rig.toward(target, by):
        return speed
    if not confirmed:
        raise FirstTouchUnknown(
            "first touch is not known (no contact search yet), so the overlap limit is not "
            "armed: run a contact search first, or confirm the move (it then goes at most "
            f"{APPROACH_SPEED * 1e3:g} mm/s, the force limit armed); nothing moved")
    return min(speed, APPROACH_SPEED)


class TripNotAcknowledged(GelrigError):
    """A move that loads the sample was asked for while an interlock trip is unacknowledged."""


@dataclass(frozen=True)
class Motion:
    """A manual motion as the GUI asks for it: ``start`` sends the non-blocking command;
    ``toward`` says whether it loads the sample (decided on the rig thread, from where the
    axis is); ``ends`` False for a motion that goes on until stopped (a rotation)."""

    start: Callable[[Rig], object]
    toward: Callable[[Rig], bool] = lambda rig: True
    ends: bool = True


def run_motion(rig: Rig, what: str, motion: Motion, control: RunControl,
               on_values: Values | None = None, tripped: bool = False) -> Guarded:
    """:func:`guarded` for a :class:`Motion`; with ``tripped`` (an unacknowledged trip) a
    motion that loads the sample is refused (:class:`TripNotAcknowledged`), nothing moved."""
    toward = motion.toward(rig)
    if tripped and toward:
        raise TripNotAcknowledged("an interlock tripped and is not acknowledged; nothing moved")
    return guarded(rig, what, lambda: motion.start(rig), control, on_values, toward,
                   motion.ends)
