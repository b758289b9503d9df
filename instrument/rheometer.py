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
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Protocol, runtime_checkable

from instrument.errors import ConfigError
from instrument.fields import Field
from instrument.identity import Identity
from instrument.units import to_si


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

    Every method may raise :class:`instrument.errors.InstrumentError` subclasses (timeout,
    framing, device error reply, disconnect) or :class:`instrument.errors.LimitError` for a
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
        """Turn at constant linear ``speed`` (m/s at the arm); the sign picks the direction."""
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

    def read_stream(self) -> list[StreamPoint]:
        """Every point recorded since the last read, oldest first."""
        ...

    def stop_stream(self) -> None:
        """Stop recording points."""
        ...

    def close(self) -> None:
        """Stop motion if any and release the transport."""
        ...


_BOUNDS: dict[str, Field] = {
    f.key: f
    for f in (
        Field("arm", "m", lo=1e-3, hi=0.5),
        Field("torque_range", "N*m", lo=0.0, hi=1.0, lo_open=True),
        Field("torque_resolution", "N*m", lo=0.0, hi=1e-3, lo_open=True),
        Field("normal_force_range", "N", lo=0.0, hi=1000.0, lo_open=True),
        Field("normal_force_resolution", "N", lo=0.0, hi=1.0, lo_open=True),
        Field("max_speed", "m/s", lo=0.0, hi=1.0, lo_open=True),
        Field("gap_min", "m", lo=0.0, hi=0.2),
        Field("gap_max", "m", lo=0.0, hi=0.2, lo_open=True),
        Field("overlap_limit", "m", lo=0.0, hi=0.01, lo_open=True),
        Field("touch_gap", "m", lo=0.0, hi=0.2),
        Field("timeout", "s", lo=0.0, hi=600.0, lo_open=True),
        Field("gap_move_timeout", "s", lo=0.0, hi=86400.0, lo_open=True),
        Field("poll_interval", "s", lo=0.0, hi=10.0, lo_open=True),
    )
}


def _check(name: str, value: float, source: str | None) -> None:
    _BOUNDS[name].check(value, source=source)


@dataclass(frozen=True)
class RheometerConfig:
    """Calibration, limits and timing of the shear-rig rheometer (SI units).

    Defaults marked UNVERIFIED in instruments.md are placeholders for the rig file to confirm:
    torque, normal-force, speed and gap limits of the MCR 501. ``touch_gap`` is the gap at
    which the spheres just touch on top of each other; a contact search finds it, and then
    gap requests deeper than ``overlap_limit`` below it are refused. ``timeout`` is the reply
    timeout on the wire (real seconds); ``gap_move_timeout`` and ``poll_interval`` run on the
    injected clock.
    """

    arm: float = 0.027
    torque_range: float = 0.2  # UNVERIFIED
    torque_resolution: float = 1e-9  # UNVERIFIED
    normal_force_range: float = 50.0  # UNVERIFIED
    normal_force_resolution: float = 1e-5  # UNVERIFIED
    max_speed: float = 5e-3  # UNVERIFIED (about 1.8 rpm at the 27 mm arm)
    gap_min: float = 0.0  # UNVERIFIED
    gap_max: float = 0.05  # UNVERIFIED
    overlap_limit: float = 1.2e-3
    touch_gap: float | None = None
    timeout: float = 2.0
    gap_move_timeout: float = 120.0
    poll_interval: float = 0.05

    def __post_init__(self) -> None:
        self._validate(None)

    def _validate(self, source: str | None) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.name == "touch_gap":
                continue
            _check(f.name, float(value), source)
        if self.gap_min >= self.gap_max:
            raise ConfigError(
                "gap_min", self.gap_min, f"must be < gap_max = {self.gap_max:g} m", source
            )

    @classmethod
    def from_mapping(
        cls, mapping: Mapping[str, object], source: str | None = None
    ) -> RheometerConfig:
        """Build from a rig-file table; values are SI numbers or strings like ``"27 mm"``.

        Unknown keys and out-of-range values raise ConfigError naming ``source``, the field,
        the value and the allowed range.
        """
        known = {f.name for f in fields(cls)}
        values: dict[str, float | None] = {}
        for key, raw in mapping.items():
            if key not in known:
                raise ConfigError(
                    key, raw, f"unknown field; allowed: {', '.join(sorted(known))}", source
                )
            if key == "touch_gap" and raw is None:
                values[key] = None
                continue
            if not isinstance(raw, str | int | float):
                raise ConfigError(key, raw, f"expected a number in {_BOUNDS[key].unit}", source)
            value = to_si(raw, _BOUNDS[key].unit, key, source)
            _check(key, value, source)
            values[key] = value
        try:
            return cls(**values)  # type: ignore[arg-type]
        except ConfigError as exc:
            if exc.source is None and source is not None:
                raise ConfigError(exc.field, exc.value, exc.allowed, source) from None
            raise

    def speed_allowed(self, speed: float) -> bool:
        """True if ``|speed|`` (m/s) is within ``max_speed``."""
        return math.isfinite(speed) and abs(speed) <= self.max_speed

    def deepest_gap(self) -> float:
        """Smallest gap (m) a request may ask for: gap_min, or the overlap limit below touch."""
        if self.touch_gap is None:
            return self.gap_min
        return max(self.gap_min, self.touch_gap - self.overlap_limit)
