"""The rigs as the runner sees them: instruments behind their contracts, a clock, the limits.

Built by the rig factory (gelrig.factory) from a rig file; a test may build one from doubles.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

import numpy as np

from gelrig.instrument.contracts.loadcell import ForceSensor
from gelrig.instrument.contracts.rheometer import Rheometer
from gelrig.instrument.contracts.stage import Stage, StageConfig
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import GelrigError, InstrumentError
from gelrig.instrument.core.fields import Config, Field, param
from gelrig.instrument.core.stage_path import StagePath
from gelrig.instrument.core.timebase import SampleClock, TimeMapping
from gelrig.instrument.physics import paper
from gelrig.protocols.caps import CappedRheometer, CappedStage
from gelrig.protocols.fence import Fence, FencedForce
from gelrig.protocols.interlocks import Interlock
from gelrig.protocols.safestop import AxisState, SafeState, stop_rheometer, stop_stage

log = logging.getLogger(__name__)

#: Force (N) above which a sample counts as loaded: the contact search's default threshold.
LOADED_FORCE = 5e-3
#: Torque (N*m) above which the shear sample counts as loaded: the shear search's default.
LOADED_TORQUE = paper.CONTACT_TORQUE
#: How far an unload moves (m) when the rig file's retract or lift after a fault is 0.
UNLOAD_DEFAULT = 2e-3


class NotHomed(GelrigError):
    """A stage move was asked for before homing: positions mean nothing yet; nothing moved."""


@dataclass(frozen=True)
class CompressionLimits(Config):
    """Interlock limits of the plate-compression rig (SI): the ``[limits]`` table."""

    section: ClassVar[str] = "limits"

    max_force: float = param(Field("max_force", "N", 2.0, 0.0, 100.0, lo_open=True,
                                   help="below the 2.5 N load cell's capacity"))
    max_overlap: float = param(Field("max_overlap", "m", 2.5e-3, 0.0, 20e-3, lo_open=True,
                                     help="past first touch", display="mm"))
    fast_speed: float = param(Field("fast_speed", "m/s", 1e-3, 0.0, 2.6e-3, lo_open=True,
                                    help="for moves away from the sphere", display="mm/s"))
    acceleration: float = param(Field("acceleration", "m/s^2", 4e-3, 0.0, 10e-3, lo_open=True,
                                      display="mm/s^2"))
    retract_on_fault: float = param(Field(
        "retract_on_fault", "m", 2e-3, 0.0, 20e-3, display="mm",
        help="after a fault, abort or trip: retract the plate this far back from first touch "
             "(0: only stop)"))
    watchdog: float = param(Field("watchdog", "s", 30.0, 0.0, 3600.0,
                                  help="fault a run that records no data for this long "
                                       "(wall time; 0: off)"))

    def guards(self) -> tuple[tuple[str, float, str], ...]:
        """(what, limit, SI unit) of each interlock, for people."""
        return ("force", self.max_force, "N"), ("overlap", self.max_overlap, "m")


@dataclass(frozen=True)
class ShearLimits(Config):
    """Interlock limits of the shear rig (SI): the ``[limits]`` table."""

    section: ClassVar[str] = "limits"

    max_torque: float = param(Field("max_torque", "N*m", 5e-3, 0.0, 1.0, lo_open=True))
    max_normal_force: float = param(Field("max_normal_force", "N", 2.0, 0.0, 100.0,
                                          lo_open=True))
    max_overlap: float = param(Field("max_overlap", "m", 1.2e-3, 0.0, 10e-3, lo_open=True,
                                     help="below the touch gap", display="mm"))
    lift_on_fault: float = param(Field(
        "lift_on_fault", "m", 2e-3, 0.0, 50e-3, display="mm",
        help="after a fault, abort or trip: raise the gap by this much (0: only stop)"))
    watchdog: float = param(Field("watchdog", "s", 30.0, 0.0, 3600.0,
                                  help="fault a run that records no data for this long "
                                       "(wall time; 0: off)"))

    def guards(self) -> tuple[tuple[str, float, str], ...]:
        """(what, limit, SI unit) of each interlock, for people."""
        return (("torque", self.max_torque, "N*m"),
                ("normal force", self.max_normal_force, "N"), ("overlap", self.max_overlap, "m"))


@dataclass
class CompressionRig:
    """Stage + force sensor of the plate-compression rig.

    What differs between the rigs is a method here, not a branch in its callers: the
    interlocks a step arms, the idle readings the GUI shows, the manual commands.
    """

    stage: Stage
    force: ForceSensor
    clock: Clock
    limits: CompressionLimits = field(default_factory=CompressionLimits)
    identities: dict[str, object] = field(default_factory=dict)
    simulated: bool = False
    close_hooks: list[Callable[[], None]] = field(default_factory=list)
    monitoring: bool = field(default=False, init=False)
    #: stage position of first touch, once a step knows it: where a safe stop retracts from
    first_touch: float | None = field(default=None, init=False)
    #: safe stop first: armed by the runner while a step runs (protocols/fence.py)
    fence: Fence = field(default_factory=Fence, init=False)
    #: the simulated instruments behind a simulated rig (the factory sets it): what bring-up's
    #: twin operator reads its answers from (issue 30); None on a real rig
    twin: object | None = field(default=None, init=False, repr=False)

    kind = "compression"

    def __post_init__(self) -> None:
        # every command goes through the rig file's caps ([stage] max_velocity, travel)
        if not isinstance(self.stage, CappedStage):
            caps = getattr(self.stage, "config", None)
            self.stage = CappedStage(self.stage, caps if isinstance(caps, StageConfig)
                                     else StageConfig(), self.fence)
        else:
            self.stage.fence = self.fence
        if not isinstance(self.force, FencedForce):
            self.force = FencedForce(self.force, self.fence)

    @property
    def stage_caps(self) -> StageConfig:
        """The ``[stage]`` limits every command is checked against."""
        return self.stage.caps if isinstance(self.stage, CappedStage) else StageConfig()

    def interlocks(self, overlap: bool = False) -> tuple[Interlock, ...]:
        """What a step checks on every sample: the force, and the overlap past first touch
        once the step knows where first touch is (``overlap``)."""
        force = Interlock("force", "force_N", self.limits.max_force, "N")
        if not overlap:
            return (force,)
        return force, Interlock("overlap", "delta_m", self.limits.max_overlap, "m",
                                absolute=False)

    def time_base(self) -> dict[str, Any]:
        """How each instrument's readings are put on the run's clock, and how well (run.json's
        ``time_base``, ADR 0241)."""
        out: dict[str, Any] = {"clock": "the run's clock (s); every column of a row refers to "
                                        "the force sample's instant"}
        path = getattr(self.stage, "path", None)
        if isinstance(path, StagePath):
            out["stage"] = path.mapping("stage").as_dict()
        else:
            out["stage"] = TimeMapping("stage", "positions interpolated between polls taken "
                                       "within each poll's request-reply window", math.nan,
                                       {}).as_dict()
        clock = getattr(self.force, "sample_clock", None)
        if isinstance(clock, SampleClock):
            out["force"] = clock.mapping("force").as_dict()
        return out

    def readings(self, monitor_rate: float = 100.0,
                 answered: Callable[[str], None] | None = None) -> dict[str, float]:
        """Live values while idle: position, motion, homed, and the latest force (mean of
        the last 0.1 s; the force input is started at ``monitor_rate`` Hz if it is not).
        ``answered("stage")`` / ``answered("force")`` as each instrument answers (the GUI's
        heartbeat: a stage that answered is not silent while the force input is waited on)."""
        status = self.stage.status()
        values = {"position_m": self.stage.position(), "moving": float(status.busy),
                  "homed": float(status.homed)}
        if answered is not None:
            answered("stage")
        try:
            if not self.monitoring:
                self.force.start(monitor_rate)
                self.monitoring = True
            block = self.force.read_block(None)
        except InstrumentError:
            self.monitoring = False  # an overflow or a stopped task: restart next time
            raise
        if answered is not None:
            answered("force")
        if len(block):
            tail = max(1, round(0.1 * self.force.rate))
            values["force_N"] = float(np.mean(block.force[-tail:]))
        return values

    def end_monitoring(self) -> None:
        """Before a run: drop the idle readout's unread samples so the run starts now."""
        if not self.monitoring:
            return
        self.monitoring = False
        try:
            self.force.read_block(None)
        except InstrumentError:
            self.force.start(self.force.rate or 100.0)

    # manual commands: each returns at once; the motion goes on under the readout
    def home(self) -> None:
        self.stage.home(wait=False)

    def move_plate(self, speed: float, target: float | None = None,
                   by: float | None = None) -> None:
        """Move the plate to ``target`` or ``by`` a distance (m) at ``speed`` (m/s); refused
        (:class:`NotHomed`) before the stage is homed."""
        self.stage.set_velocity(speed, self.limits.acceleration)  # the caps refuse first
        if not self.stage.status().homed:
            raise NotHomed("the stage is not homed, so its positions mean nothing yet; "
                           "nothing moved")
        if target is not None:
            self.stage.move_to(target, wait=False)
        elif by is not None:
            self.stage.move_by(by, wait=False)

    def toward(self, target: float | None = None, by: float | None = None) -> bool:
        """Whether a manual move loads the sample (toward the sphere: + direction)."""
        if by is not None:
            return by > 0
        return target is not None and target > self.stage.position()

    def load_state(self, values: Mapping[str, float]) -> str | None:
        """Why the sample counts as loaded, from idle readings, or None: a force above
        :data:`LOADED_FORCE` or the plate past first touch (when known)."""
        force, where = values.get("force_N"), values.get("position_m")
        if force is not None and force > LOADED_FORCE:
            return f"{force * 1e3:.3g} mN on the sample"
        if where is not None and self.first_touch is not None and where > self.first_touch:
            return f"plate {(where - self.first_touch) * 1e3:.3f} mm past first touch"
        return None

    def unload(self, budget: float = 30.0) -> SafeState:
        """Stop and retract the plate to the rig's safe position: ``retract_on_fault`` back
        from first touch (:data:`UNLOAD_DEFAULT` if that is 0), or to the end of travel away
        from the sphere when first touch is not known; returns what was verified."""
        limits = self.limits
        retract = limits.retract_on_fault or UNLOAD_DEFAULT
        if self.first_touch is None:
            retract = math.inf  # where the sphere is is not known: all the way back
        return self._stopped("unload the sample", lambda: stop_stage(
            self.stage, self.clock, retract, self.first_touch, limits.fast_speed,
            limits.acceleration, budget, self.force_now, LOADED_FORCE))

    def force_now(self) -> float:
        """The load on the sample now (N): the mean of the latest 0.1 s of samples (the
        force input started at 100 Hz if it is not running)."""
        force = self.force
        if force.rate <= 0:
            force.start(100.0)
            self.monitoring = True
        block = force.read_block(None)
        want = max(1, round(0.1 * force.rate))
        if len(block) < want:
            block = force.read_block(want)
        return float(np.mean(block.force[-want:]))

    def _stopped(self, reason: str, stop: Callable[[], AxisState]) -> SafeState:
        """Run a safe stop's instrument calls past the fence; timed and recorded there."""
        start = time.monotonic()
        with self.fence.open():
            safe = SafeState(reason, [stop()], time.monotonic() - start)
        self.fence.record(safe)
        return safe

    def tare(self, duration: float, monitor_rate: float = 100.0) -> float:
        """Zero the force on ``duration`` s of samples; returns the removed offset (N)."""
        if not self.monitoring:
            self.force.start(monitor_rate)
            self.monitoring = True
        return self.force.tare(duration)

    def stop_all(self) -> None:
        """Stop every motion at once; never raises (it runs on the way out of faults)."""
        try:
            self.stage.stop(immediate=True)
        except InstrumentError as exc:  # a frozen or lost instrument: one line, no traceback
            log.error("stage stop failed: %s: %s", type(exc).__name__, exc)
        except Exception:
            log.exception("stage stop failed")

    def safe_stop(self, reason: str, budget: float = 15.0, faulted: str = "") -> SafeState:
        """Stop, read back, retract the plate ``limits.retract_on_fault`` from first touch (or,
        first touch unknown, until the load reads below :data:`LOADED_FORCE`, or to the end
        of travel when the ``faulted`` instrument is the force input); returns what was
        verified. Never raises; every call is bounded (``budget`` s)."""
        limits = self.limits
        force = None if faulted == "force" else self.force_now
        return self._stopped(reason, lambda: stop_stage(
            self.stage, self.clock, limits.retract_on_fault, self.first_touch,
            limits.fast_speed, limits.acceleration, budget, force, LOADED_FORCE))

    def close(self) -> None:
        with self.fence.open():  # closing is not a step's cleanup: it always reaches them
            self.stop_all()
            _run_all((self.force.stop, self.force.close, self.stage.close, *self.close_hooks))


@dataclass
class ShearRig:
    """The rheometer of the inter-particle shear rig (see :class:`CompressionRig`)."""

    rheometer: Rheometer
    clock: Clock
    limits: ShearLimits = field(default_factory=ShearLimits)
    identities: dict[str, object] = field(default_factory=dict)
    simulated: bool = False
    close_hooks: list[Callable[[], None]] = field(default_factory=list)
    #: safe stop first: armed by the runner while a step runs (protocols/fence.py)
    fence: Fence = field(default_factory=Fence, init=False)
    #: the simulated rheometer behind a simulated rig (the factory sets it); None on a real
    #: rig (issue 30: bring-up's twin operator)
    twin: object | None = field(default=None, init=False, repr=False)

    kind = "shear"

    def __post_init__(self) -> None:
        # every command goes through the rig file's caps (max_speed, gap and overlap)
        if not isinstance(self.rheometer, CappedRheometer):
            self.rheometer = CappedRheometer(self.rheometer, self.limits.max_overlap,
                                             self.fence)
        else:
            self.rheometer.fence = self.fence

    def time_base(self) -> dict[str, Any]:
        """How the rheometer's stream is put on the run's clock (run.json's ``time_base``):
        angle, torque and normal force of a record share the instrument's time of it."""
        rheo = self.rheometer
        unc = float(getattr(rheo, "stream_start_uncertainty", math.nan))
        return {"clock": "the run's clock (s)",
                "rheometer": TimeMapping(
                    "rheometer", "stream: t = t0 + the record's instrument time; t0 the middle "
                    "of the window in which the stream was started", unc,
                    {"start_uncertainty_s": unc}).as_dict()}

    @property
    def touch_gap(self) -> float | None:
        """The gap where the spheres touch, once known (m)."""
        rheo = self.rheometer
        return rheo.touch_gap if isinstance(rheo, CappedRheometer) else None

    def know_touch_gap(self, touch_gap: float) -> None:
        """From now on refuse gaps more than the overlap limit below ``touch_gap`` (m)."""
        if isinstance(self.rheometer, CappedRheometer):
            self.rheometer.touch_gap = touch_gap

    def gap_error(self, gap: float) -> str | None:
        """Why the lift may not go to ``gap`` (m) under the rig's caps, or None."""
        return self.rheometer.gap_error(gap) if isinstance(self.rheometer, CappedRheometer) \
            else None

    def interlocks(self) -> tuple[Interlock, ...]:
        """What a step checks on every sample: torque and normal force."""
        return (Interlock("torque", "torque_Nm", self.limits.max_torque, "N*m"),
                Interlock("normal force", "normal_force_N", self.limits.max_normal_force, "N"))

    def readings(self, monitor_rate: float = 100.0,
                 answered: Callable[[str], None] | None = None) -> dict[str, float]:
        """Live values while idle: gap, arm angle and arc, torque, normal force, motion;
        ``answered("rheometer")`` once it has answered (as :meth:`CompressionRig.readings`)."""
        rheo = self.rheometer
        status = rheo.status()
        values = {"gap_m": rheo.gap(), "angle_rad": rheo.angle(), "theta_m": rheo.theta(),
                  "torque_Nm": rheo.torque(), "normal_force_N": rheo.normal_force(),
                  "moving": float(status.busy), "gap_referenced": float(status.gap_referenced)}
        if answered is not None:
            answered("rheometer")
        return values

    def end_monitoring(self) -> None:
        """Nothing streams while idle on this rig."""

    # manual commands: each returns at once
    def load_state(self, values: Mapping[str, float]) -> str | None:
        """Why the sample counts as loaded, from idle readings, or None: the gap below the
        touch gap (when known), a torque above :data:`LOADED_TORQUE` or a normal force above
        :data:`LOADED_FORCE`."""
        gap = values.get("gap_m")
        touch = self.rheometer.touch_gap if isinstance(self.rheometer, CappedRheometer) \
            else None
        if gap is not None and touch is not None and gap < touch:
            return f"gap {(touch - gap) * 1e3:.3f} mm below the touch gap"
        torque, normal = values.get("torque_Nm"), values.get("normal_force_N")
        if torque is not None and abs(torque) > LOADED_TORQUE:
            return f"torque {torque * 1e3:.3g} mN*m on the sample"
        if normal is not None and abs(normal) > LOADED_FORCE:
            return f"normal force {normal * 1e3:.3g} mN on the sample"
        return None

    def unload(self, budget: float = 15.0) -> SafeState:
        """Stop the arm and lift it ``lift_on_fault`` (:data:`UNLOAD_DEFAULT` if that is 0);
        returns what was verified."""
        return self._stopped("unload the sample", lambda: stop_rheometer(
            self.rheometer, self.clock, self.limits.lift_on_fault or UNLOAD_DEFAULT, budget,
            *self._lift_until()))

    def _lift_until(self) -> tuple[Callable[[], float] | None, float]:
        """With the touch gap unknown, the lift goes on until the normal force reads below
        :data:`LOADED_FORCE`."""
        if self.touch_gap is not None:
            return None, math.inf
        return self.rheometer.normal_force, LOADED_FORCE

    def _stopped(self, reason: str, stop: Callable[[], AxisState]) -> SafeState:
        """Run a safe stop's instrument calls past the fence; timed and recorded there."""
        start = time.monotonic()
        with self.fence.open():
            safe = SafeState(reason, [stop()], time.monotonic() - start)
        self.fence.record(safe)
        return safe

    def zero_gap(self) -> None:
        self.rheometer.zero_gap()

    def set_gap(self, gap: float) -> None:
        self.rheometer.set_gap(gap, wait=False)

    def rotate(self, speed: float) -> None:
        """Turn at ``speed`` (m/s at the arm; + clockwise)."""
        self.rheometer.rotate(speed)

    def hold(self) -> None:
        self.rheometer.hold()

    def stop_all(self) -> None:
        """Stop every motion at once; never raises (it runs on the way out of faults)."""
        try:
            self.rheometer.stop()
        except InstrumentError as exc:  # a frozen or lost instrument: one line, no traceback
            log.error("rheometer stop failed: %s: %s", type(exc).__name__, exc)
        except Exception:
            log.exception("rheometer stop failed")

    def safe_stop(self, reason: str, budget: float = 15.0, faulted: str = "") -> SafeState:
        """Stop the arm, read it back, lift it ``limits.lift_on_fault`` (with the touch gap
        unknown, until the normal force reads below :data:`LOADED_FORCE`); returns what was
        verified. Never raises; every call is bounded (``budget`` s)."""
        return self._stopped(reason, lambda: stop_rheometer(
            self.rheometer, self.clock, self.limits.lift_on_fault, budget, *self._lift_until()))

    def close(self) -> None:
        with self.fence.open():  # closing is not a step's cleanup: it always reaches them
            self.stop_all()
            _run_all((self.rheometer.close, *self.close_hooks))


def _run_all(closers: tuple[Callable[[], None], ...]) -> None:
    """Call every closer even if some fail (each failure is logged): release everything."""
    for closer in closers:
        name = getattr(closer, "__qualname__", repr(closer))
        try:
            closer()
        except InstrumentError as exc:  # a frozen or lost instrument: one line, no traceback
            log.error("closing: %s failed: %s: %s", name, type(exc).__name__, exc)
        except Exception:
            log.exception("closing: %s failed", name)


Rig = CompressionRig | ShearRig
RigT = TypeVar("RigT", CompressionRig, ShearRig)
"""A step or context generic over the rig it runs on."""
