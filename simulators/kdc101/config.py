"""What the simulated KDC101 + Z825B is: its true encoder scale, travel and power-on state.

A :class:`~gelrig.instrument.core.fields.Config` like every configuration (ADR 0052): each
field is declared once, with its unit, default, range and help, and ``gelrig sim serve
kdc101`` offers them as options from these declarations. The actuator's facts (travel, caps,
the nominal encoder scale) are the stage contract's numbers, the ones the rig file's
``[stage]`` table defaults to; the simulated controller's direction convention is the
``[stage] direction`` field's (ADR 0100). Light to import (no numpy).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from gelrig.instrument.contracts.stage import (
    DIRECTION,
    Z825B_ACCEL_CAP_M_S2,
    Z825B_COUNTS_PER_MM,
    Z825B_MAX_VELOCITY_M_S,
    Z825B_TRAVEL_M,
)
from gelrig.instrument.core.fields import Config, Field, Where, param
from gelrig.instrument.physics.truth import TIMING

#: The KDC101's reply and status latency to the host as documented: FTDI's default latency
#: timer, 16 ms (FTDI AN232B-04: a short message waits in the adapter until it expires);
#: whether the KDC101's adapter or the host's driver sets it lower is UNVERIFIED.
DOCUMENTED_REPLY_LATENCY_S = 0.016


@dataclass(frozen=True)
class SimConfig(Config):
    """The simulated hardware. Positions are extensions from the home limit switch (m)."""

    section: ClassVar[str] = "kdc101"
    exact_integers: ClassVar[bool] = True

    serial_number: int = param(Field("serial", "", 27000001, 0, 99_999_999, integer=True,
                                     help="serial number (27xxxxxx)"))
    counts_per_mm: float = param(Field("counts_per_mm", "", Z825B_COUNTS_PER_MM, 0.0, 1e6,
                                       lo_open=True, help="the actuator's true encoder scale "
                                       "(may differ from the rig file's calibration)"))
    travel_m: float = param(Field("travel", "m", Z825B_TRAVEL_M, 0.0, 1.0, lo_open=True,
                                  help="actuator travel", display="mm"))
    start_position_m: float = param(Field("start_position", "m", 5e-3, 0.0, 1.0, display="mm",
                                          help="extension from the home switch at power-on"))
    home_offset_m: float = param(Field("home_offset", "m", 0.1e-3, 0.0, 1.0, display="mm",
                                       help="home position past the switch (UNVERIFIED)"))
    max_velocity_m_s: float = param(Field("max_velocity", "m/s", 2.0e-3, 0.0, 1.0,
                                          lo_open=True, display="mm/s",
                                          help="power-on velocity (UNVERIFIED)"))
    acceleration_m_s2: float = param(Field("acceleration", "m/s^2", 1.5e-3, 0.0, 10.0,
                                           lo_open=True, display="mm/s^2",
                                           help="power-on acceleration (UNVERIFIED)"))
    home_velocity_m_s: float = param(Field("home_velocity", "m/s", 1.0e-3, 0.0, 1.0,
                                           lo_open=True, display="mm/s",
                                           help="power-on homing velocity"))
    velocity_cap_m_s: float = param(Field("velocity_cap", "m/s", Z825B_MAX_VELOCITY_M_S, 0.0,
                                          1.0, lo_open=True, display="mm/s",
                                          help="requests above are refused"))
    accel_cap_m_s2: float = param(Field("accel_cap", "m/s^2", Z825B_ACCEL_CAP_M_S2, 0.0, 10.0,
                                        lo_open=True, display="mm/s^2",
                                        help="requests above are refused"))
    direction: str = param(DIRECTION)
    update_period_s: float = param(Field(
        "update_period", "s", 0.1, 0.0, 10.0, lo_open=True,
        help="status update period (APT document: 100 ms)"))
    timing: str = param(TIMING)
    reply_latency_s: float | None = param(Field(
        "reply_latency", "s", None, 0.0, 1.0, optional=True,
        help="from a request's arrival (or a status update's moment) to its bytes reaching "
             "the host: the USB link and the FTDI latency timer (default: timing's, 0 ideal, "
             "16 ms documented; real value UNVERIFIED)"))
    firmware: tuple[int, int, int] = field(default=(3, 0, 10))
    stage_id: int = 9  # Z825 in the KDC101 stage table

    def validate(self, where: Where) -> None:
        if not 27000000 <= self.serial_number <= 27999999:
            raise where.error("serial", self.serial_number, "a KDC101 serial is 27xxxxxx")
        if not self.start_position_m <= self.travel_m:
            raise where.error("start_position", self.start_position_m,
                              f"must lie in [0, {self.travel_m:g}] m")
        if not self.home_offset_m < self.travel_m:
            raise where.error("home_offset", self.home_offset_m,
                              f"must lie in [0, {self.travel_m:g}) m")

    @property
    def reply_latency(self) -> float:
        """The reply latency in force (s): the field's, else the timing preset's."""
        if self.reply_latency_s is not None:
            return self.reply_latency_s
        return DOCUMENTED_REPLY_LATENCY_S if self.timing == "documented" else 0.0

    @property
    def counts_per_m(self) -> float:
        return self.counts_per_mm * 1e3
