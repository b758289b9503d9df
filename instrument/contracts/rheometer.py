"""The rheometer contract of the inter-particle shear rig, in SI units.

Protocols and the runner program against :class:`Rheometer` only; the MCR 501 driver meets it
over the wire (hardware or simulator). Sign convention (physics.md section 2,
docs/decisions/0022): a positive speed turns the arm clockwise, which is the direction of
increasing angle; the motor torque of a clockwise pass is positive while the contact resists.

:class:`RheometerConfig` holds the calibration and safety limits of the rig file. The MCR 501
limits are UNVERIFIED (instruments.md), so every one is a configurable default here, never a
constant in code.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Protocol, overload, runtime_checkable

from gelrig.instrument.core.fields import Config, Field, Where, param
from gelrig.instrument.core.identity import Identity

if TYPE_CHECKING:  # numpy is imported when a block is built: the configuration stays light
    from gelrig.instrument.core.arrays import FloatArray


@dataclass(frozen=True)
class StreamPoint:
    """One point of the measurement stream.

    ``t`` is on the caller's clock (s), anchored at ``start_stream``; ``angle`` (rad) and
    ``theta = angle * arm`` (m) are arm positions; ``torque`` (N m, lab frame), ``normal_force``
    (N, positive pushing the spheres apart) and ``gap`` (m) are as the instrument reports them.
    """

    t: float
    angle: float
    theta: float
    torque: float
    normal_force: float
    gap: float



class StreamBlock(Sequence[StreamPoint]):
    """Stream points as columns (1-D float arrays of one length, SI units, oldest first).

    What :meth:`Rheometer.read_stream` returns from the driver: a read carries tens of points,
    and the recorder wants columns, so no per-point object is made on the way. It is still a
    sequence of :class:`StreamPoint` (built on access) for callers that iterate.
    """

    __slots__ = ("angle", "gap", "normal_force", "t", "theta", "torque")

    def __init__(self, t: FloatArray, angle: FloatArray, theta: FloatArray,
                 torque: FloatArray, normal_force: FloatArray, gap: FloatArray):
        self.t, self.angle, self.theta = t, angle, theta
        self.torque, self.normal_force, self.gap = torque, normal_force, gap

    @classmethod
    def of(cls, points: Iterable[StreamPoint]) -> StreamBlock:
        """``points`` as a block (a block is returned as it is)."""
        if isinstance(points, StreamBlock):
            return points
        import numpy as np

        rows = [(p.t, p.angle, p.theta, p.torque, p.normal_force, p.gap) for p in points]
        if not rows:
            return cls(*(np.empty(0) for _ in range(6)))
        return cls(*(np.array(column, dtype=float) for column in zip(*rows, strict=True)))

    def __len__(self) -> int:
        return len(self.t)

    @overload
    def __getitem__(self, index: int) -> StreamPoint: ...

    @overload
    def __getitem__(self, index: slice) -> StreamBlock: ...

    def __getitem__(self, index: int | slice) -> StreamPoint | StreamBlock:
        if isinstance(index, slice):
            return StreamBlock(self.t[index], self.angle[index], self.theta[index],
                               self.torque[index], self.normal_force[index], self.gap[index])
        return StreamPoint(float(self.t[index]), float(self.angle[index]),
                           float(self.theta[index]), float(self.torque[index]),
                           float(self.normal_force[index]), float(self.gap[index]))

    def __iter__(self) -> Iterator[StreamPoint]:
        return (self[i] for i in range(len(self)))

    def __eq__(self, other: object) -> bool:
        """Equal to any sequence of the same points (a list of StreamPoint included)."""
        if not isinstance(other, Sequence):
            return NotImplemented
        return len(self) == len(other) and list(self) == list(other)

    __hash__ = None  # type: ignore[assignment]  # mutable arrays, like a list


@dataclass(frozen=True)
class RheometerStatus:
    """The instrument's state word, decoded.

    ``mode`` is ``"idle"`` (speed set to zero), ``"rotating"`` or ``"holding"`` (position held);
    ``accelerating`` is true while the motor ramps towards its set speed.
    """

    mode: str
    gap_moving: bool
    gap_referenced: bool
    streaming: bool
    accelerating: bool
    fault: bool
    overflow: bool

    @property
    def busy(self) -> bool:
        """True while anything moves: the arm turns or ramps, or the lift travels."""
        return self.mode == "rotating" or self.accelerating or self.gap_moving


@runtime_checkable
class Rheometer(Protocol):
    """A rotational rheometer carrying the upper sphere on an arm; SI units throughout.

    Every method may raise :class:`gelrig.instrument.core.errors.InstrumentError` subclasses
    (timeout,
    framing, device error reply, disconnect) or :class:`gelrig.instrument.core.errors.LimitError`
    for a
    request outside :attr:`config`. A failure while the arm may be turning stops it first.
    """

    @property
    def config(self) -> RheometerConfig:
        """Calibration and limits in force."""
        ...

    def identify(self) -> Identity:
        """Model, serial number and firmware."""
        ...

    def status(self) -> RheometerStatus:
        """The instrument's state word."""
        ...

    def zero_gap(self) -> None:
        """Run the instrument's gap referencing; gap moves are refused before it."""
        ...

    def set_gap(self, gap: float, wait: bool = True) -> None:
        """Move the lift to ``gap`` (m); with ``wait``, return once it has arrived."""
        ...

    def gap(self) -> float:
        """Current gap (m)."""
        ...

    def rotate(self, speed: float) -> None:
        """Turn at constant linear ``speed`` (m/s at the arm); the sign picks the direction.

        The rotation goes on only while gelrig renews it (ADR 0201): any later call renews
        it when due, so a caller that waits calls something (:meth:`keep_alive`) at least
        every ``config.motion_bound / 4``; left alone, the instrument stops within
        ``config.motion_bound``.
        """
        ...

    def keep_alive(self) -> None:
        """Renew the rotation in progress if it is due (a no-op otherwise)."""
        ...

    def stop(self) -> None:
        """Ramp the speed to zero."""
        ...

    def hold(self) -> None:
        """Ramp to rest and hold that position under position control."""
        ...

    def angle(self) -> float:
        """Arm angle (rad), increasing clockwise, zero where the instrument started."""
        ...

    def theta(self) -> float:
        """Arc travel of the arm tip, ``angle * arm`` (m): the paper's theta."""
        ...

    def torque(self) -> float:
        """Motor torque (N m), lab frame."""
        ...

    def normal_force(self) -> float:
        """Normal force (N), positive pushing the spheres apart."""
        ...

    def start_stream(self, interval: float) -> None:
        """Start recording points every ``interval`` seconds on the instrument."""
        ...

    def read_stream(self) -> Sequence[StreamPoint]:
        """Every point recorded since the last read, oldest first (the MCR 501 driver gives a
        :class:`StreamBlock`). Points the instrument dropped are never skipped silently: a
        driver raises :class:`gelrig.instrument.core.errors.InstrumentError` naming the loss."""
        ...

    def stop_stream(self) -> None:
        """Stop recording points."""
        ...

    def close(self) -> None:
        """Stop motion if any and release the transport."""
        ...


@dataclass(frozen=True)
class RheometerConfig(Config):
    """Calibration, limits and timing of the shear-rig rheometer (SI units).

    Defaults marked UNVERIFIED in instruments.md are placeholders for the rig file to confirm:
    torque, normal-force, speed and gap limits of the MCR 501. ``touch_gap`` is the gap at
    which the spheres just touch on top of each other; a contact search finds it, and then
    gap requests deeper than ``overlap_limit`` below it are refused. ``timeout`` is the reply
    timeout on the wire (real seconds); ``gap_move_timeout`` and ``poll_interval`` run on the
    injected clock.
    """

    section: ClassVar[str] = "rheometer"

    arm: float = param(Field("arm", "m", 0.027, 1e-3, 0.5, help="arm length", display="mm"))
    torque_range: float = param(Field("torque_range", "N*m", 0.2, 0.0, 1.0, lo_open=True,
                                      help="UNVERIFIED"))
    torque_resolution: float = param(Field("torque_resolution", "N*m", 1e-9, 0.0, 1e-3,
                                           lo_open=True, help="UNVERIFIED"))
    normal_force_range: float = param(Field("normal_force_range", "N", 50.0, 0.0, 1000.0,
                                            lo_open=True, help="UNVERIFIED"))
    normal_force_resolution: float = param(Field("normal_force_resolution", "N", 1e-5, 0.0, 1.0,
                                                 lo_open=True, help="UNVERIFIED"))
    max_speed: float = param(Field("max_speed", "m/s", 5e-3, 0.0, 1.0, lo_open=True,
                                   help="UNVERIFIED (about 1.8 rpm at the 27 mm arm)",
                                   display="mm/s"))
    gap_min: float = param(Field("gap_min", "m", 0.0, 0.0, 0.2, help="UNVERIFIED",
                                 display="mm"))
    gap_max: float = param(Field("gap_max", "m", 0.05, 0.0, 0.2, lo_open=True,
                                 help="UNVERIFIED", display="mm"))
    overlap_limit: float = param(Field("overlap_limit", "m", 1.2e-3, 0.0, 0.01, lo_open=True,
                                       display="mm"))
    touch_gap: float | None = param(Field("touch_gap", "m", None, 0.0, 0.2, optional=True,
                                          help="gap at first touch, if known", display="mm"))
    timeout: float = param(Field("timeout", "s", 2.0, 0.0, 600.0, lo_open=True,
                                 help="deadline of one reply on the wire"))
    gap_move_timeout: float = param(Field("gap_move_timeout", "s", 120.0, 0.0, 86400.0,
                                          lo_open=True))
    poll_interval: float = param(Field("poll_interval", "s", 0.05, 0.0, 10.0, lo_open=True))
    motion_bound: float = param(Field("motion_bound", "s", 2.0, 0.5, 10.0,
                                      help="a rotation ends by itself within this long after "
                                           "gelrig last renewed it (ADR 0201)"))

    # The sensors' noise as measured at bring-up (issue 30): the twin's, unless the
    # [simulator] table sets its own; None: not measured.
    torque_noise: float | None = param(Field("torque_noise", "N*m", None, 0.0, 1e-3,
                                             optional=True, help="torque noise measured at "
                                             "bring-up (rms, unloaded)"))
    normal_force_noise: float | None = param(Field("normal_force_noise", "N", None, 0.0, 0.1,
                                                   optional=True, help="normal-force noise "
                                                   "measured at bring-up (rms, unloaded)"))

    def validate(self, where: Where) -> None:
        if self.gap_min >= self.gap_max:
            raise where.error("gap_min", self.gap_min, f"must be < gap_max = {self.gap_max:g} m")

    def speed_allowed(self, speed: float) -> bool:
        """True if ``|speed|`` (m/s) is within ``max_speed``."""
        return math.isfinite(speed) and abs(speed) <= self.max_speed

    def deepest_gap(self) -> float:
        """Smallest gap (m) a request may ask for: gap_min, or the overlap limit below touch."""
        if self.touch_gap is None:
            return self.gap_min
        return max(self.gap_min, self.touch_gap - self.overlap_limit)
