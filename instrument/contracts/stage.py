"""The linear stage contract: what protocols program against, whatever drives the plate.

SI units throughout (metres, m/s, m/s^2, seconds). Device units (encoder counts, APT velocity
units) exist only inside a driver. ``StageConfig`` is the ``[stage]`` table of a rig file,
validated field by field so a bad value is reported with its file, field and allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

from gelrig.instrument.core.fields import Choice, Config, Field, Flag, Where, param
from gelrig.instrument.core.identity import Identity


@dataclass(frozen=True)
class StageStatus:
    """Decoded status of one stage axis; ``raw`` keeps the device's bit word for the record."""

    raw: int
    moving: bool
    homing: bool
    homed: bool
    enabled: bool
    motor_connected: bool
    at_lower_limit: bool
    at_upper_limit: bool
    position_error: bool
    error: bool

    @property
    def busy(self) -> bool:
        """True while any motion (move, jog, velocity move or homing) is in progress."""
        return self.moving or self.homing


@runtime_checkable
class Stage(Protocol):
    """A single-axis linear stage, in SI units. Positions are those of the homed axis.

    Every wait goes through the clock the stage was built with; every failure is a typed
    ``gelrig.instrument.core.errors`` error; a fault while moving commands a stop before it is
    raised.
    """

    def identify(self) -> Identity:
        """Ask the controller who it is (what run.json records beside every run)."""
        ...

    def enable(self) -> None:
        """Energise the motor (a no-op if already enabled)."""
        ...

    def home(self, wait: bool = True, timeout: float | None = None) -> None:
        """Find the home switch and zero the position there."""
        ...

    def set_velocity(self, max_m_s: float, accel_m_s2: float) -> None:
        """Set the trapezoid used by later moves (checked against the configured limits)."""
        ...

    def move_to(self, position_m: float, wait: bool = True, timeout: float | None = None) -> None:
        """Absolute move; LimitError before anything moves if outside the software limits."""
        ...

    def move_by(self, distance_m: float, wait: bool = True, timeout: float | None = None) -> None:
        """Relative move; the end point is checked against the software limits first."""
        ...

    def move_velocity(self, direction: int) -> None:
        """Move at the configured velocity, +1 towards larger positions, -1 towards smaller."""
        ...

    def keep_alive(self) -> None:
        """Renew the motion in progress if its segment is due (a no-op otherwise).

        A motion that would last longer than ``config.motion_bound_s`` is sent as bounded
        segments that gelrig renews while it runs (ADR 0201): any call renews a due segment,
        and this one does nothing else. A caller that starts a motion without waiting for it
        calls something at least every ``motion_bound_s / 4``.
        """
        ...

    def stop(self, immediate: bool = True) -> None:
        """Stop at once (``immediate``) or along the deceleration ramp (profiled)."""
        ...

    def position(self) -> float:
        """Current position in metres (encoder counts / calibration)."""
        ...

    def status(self) -> StageStatus:
        """Current status bits, decoded."""
        ...

    def is_moving(self) -> bool:
        """True while a move or homing is in progress."""
        ...

    def wait_until_stopped(self, timeout: float | None = None) -> None:
        """Block (on the clock) until motion ends; InstrumentTimeout (and a stop) if it doesn't."""
        ...

    def close(self) -> None:
        """Release the transport (does not move the stage)."""
        ...


#: Direction conventions of an APT stage controller (ADR 0100): whether the protocol's
#: "forward" code and bits mean larger position counts. A KDC101 with a Z8 actuator, as both
#: public clients (pylablib, thorlabs-apt-device) encode it, is ``forward_is_negative``.
FORWARD_IS_NEGATIVE = "forward_is_negative"
FORWARD_IS_POSITIVE = "forward_is_positive"
DIRECTIONS = (FORWARD_IS_NEGATIVE, FORWARD_IS_POSITIVE)

# Z825B actuator facts (instruments.md); the accel cap is UNVERIFIED, so generous. The stage
# simulator's hardware (simulators/kdc101/config.py) is built from the same numbers.
Z825B_MAX_VELOCITY_M_S = 2.6e-3
Z825B_ACCEL_CAP_M_S2 = 10e-3
Z825B_TRAVEL_M = 25e-3
#: Encoder counts per mm of the Z825B, as the protocol document gives it (ADR 0003 for the
#: 34304 conflict): the rig file's calibration default and the simulated actuator's true scale.
Z825B_COUNTS_PER_MM = 34554.96

#: What the APT "forward" code means (ADR 0100): the ``[stage]`` field, which the simulated
#: controller follows too.
DIRECTION = Choice("direction", DIRECTIONS, FORWARD_IS_NEGATIVE,
                   help="what the APT 'forward' code means (ADR 0100)")


@dataclass(frozen=True)
class StageConfig(Config):
    """Calibration, safety limits and timing of the compression-rig stage (KDC101 + Z825B).

    ``counts_per_mm`` defaults to the protocol document's :data:`Z825B_COUNTS_PER_MM` (see ADR
    0003 for the 34304 conflict); velocity and acceleration factors convert mm/s and mm/s^2 to
    APT units.
    Software limits are positions of the homed axis; nothing outside them is ever commanded.
    """

    section: ClassVar[str] = "stage"

    counts_per_mm: float = param(Field("counts_per_mm", "", Z825B_COUNTS_PER_MM, 1e3, 1e6,
                                       lo_open=True, help="encoder counts per mm"))
    velocity_factor: float = param(Field("velocity_factor", "", 772981.3692, 1e3, 1e9,
                                         lo_open=True, help="APT velocity units per mm/s"))
    accel_factor: float = param(Field("accel_factor", "", 263.8443072, 1e-3, 1e6, lo_open=True,
                                      help="APT acceleration units per mm/s^2"))
    min_position_m: float = param(Field("min_position", "m", 0.0, 0.0, Z825B_TRAVEL_M,
                                        help="software travel limit", display="mm"))
    max_position_m: float = param(Field("max_position", "m", 12e-3, 0.0, Z825B_TRAVEL_M,
                                        help="software travel limit", display="mm"))
    max_velocity_m_s: float = param(Field("max_velocity", "m/s", 2.3e-3, 0.0,
                                          Z825B_MAX_VELOCITY_M_S, lo_open=True,
                                          help="cap on every commanded speed", display="mm/s"))
    acceleration_m_s2: float = param(Field("acceleration", "m/s^2", 4e-3, 0.0,
                                           Z825B_ACCEL_CAP_M_S2, lo_open=True,
                                           display="mm/s^2"))
    home_velocity_m_s: float = param(Field("home_velocity", "m/s", 1e-3, 0.0,
                                           Z825B_MAX_VELOCITY_M_S, lo_open=True,
                                           display="mm/s"))
    reply_timeout_s: float = param(Field("reply_timeout", "s", 2.0, 0.0, 60.0, lo_open=True,
                                         help="deadline of one request on the wire"))
    move_timeout_s: float = param(Field("move_timeout", "s", 60.0, 0.0, 3600.0, lo_open=True))
    poll_interval_s: float = param(Field("poll_interval", "s", 0.05, 0.0, 1.0, lo_open=True))
    motion_bound_s: float = param(Field("motion_bound", "s", 2.0, 0.5, 10.0,
                                        help="a motion ends by itself within this long after "
                                             "gelrig last renewed it (ADR 0201)"))
    direction: str = param(DIRECTION)
    link_latency_s: float = param(Field(
        "link_latency", "s", 0.016, 0.0, 1.0,
        help="longest a message from the controller may wait on its way to the host (FTDI's "
             "default latency timer, 16 ms; the adapter's setting UNVERIFIED): a status "
             "update's window opens this long before the input was last found empty"))
    status_updates: bool = param(Flag(
        "status_updates", False,
        help="ask for the controller's status updates (every 100 ms) and take each as a "
             "position report within its arrival window (issue 24)"))

    def validate(self, where: Where) -> None:
        if not self.min_position_m < self.max_position_m:
            raise where.error("min_position", self.min_position_m,
                              f"must be < max_position ({self.max_position_m:g} m)")

    # Conversions used by drivers (mm only at the wire).
    def counts_from_m(self, position_m: float) -> int:
        """Encoder counts for a position or distance in metres (rounded)."""
        return round(position_m * 1e3 * self.counts_per_mm)

    def m_from_counts(self, counts: int) -> float:
        """Metres for a number of encoder counts."""
        return counts / self.counts_per_mm * 1e-3

    def apt_velocity(self, velocity_m_s: float) -> int:
        """APT velocity units for m/s."""
        return round(velocity_m_s * 1e3 * self.velocity_factor)

    def apt_acceleration(self, accel_m_s2: float) -> int:
        """APT acceleration units for m/s^2."""
        return round(accel_m_s2 * 1e3 * self.accel_factor)

    def velocity_from_apt(self, units: int) -> float:
        """m/s for APT velocity units."""
        return units / self.velocity_factor * 1e-3

    def accel_from_apt(self, units: int) -> float:
        """m/s^2 for APT acceleration units."""
        return units / self.accel_factor * 1e-3

    def check_position(self, position_m: float) -> None:
        """Raise LimitError if ``position_m`` lies outside the software travel limits."""
        from gelrig.instrument.core.errors import LimitError

        if not math.isfinite(position_m) or not (
            self.min_position_m <= position_m <= self.max_position_m
        ):
            raise LimitError(
                f"target {position_m * 1e3:.4f} mm is outside the software travel limits "
                f"[{self.min_position_m * 1e3:.4f}, {self.max_position_m * 1e3:.4f}] mm; "
                "nothing moved"
            )

    def check_velocity(self, max_m_s: float, accel_m_s2: float) -> None:
        """Raise LimitError if a velocity or acceleration is outside the actuator's range."""
        from gelrig.instrument.core.errors import LimitError

        if not 0 < max_m_s <= Z825B_MAX_VELOCITY_M_S:
            raise LimitError(
                f"velocity {max_m_s * 1e3:.4f} mm/s outside (0, "
                f"{Z825B_MAX_VELOCITY_M_S * 1e3:.1f}] mm/s"
            )
        if not 0 < accel_m_s2 <= Z825B_ACCEL_CAP_M_S2:
            raise LimitError(
                f"acceleration {accel_m_s2 * 1e3:.4f} mm/s^2 outside (0, "
                f"{Z825B_ACCEL_CAP_M_S2 * 1e3:.1f}] mm/s^2"
            )
