"""KDC101 + Z825B bring-up: identify, home, direction, scale, backlash, velocity.

The scale is found as a person at the rig would: the plate is moved in steps over a few mm,
a dial gauge resting on it is read after each step, and encoder counts are fitted against
the readings (counts per mm, with its standard uncertainty from the fit's residuals). The
direction convention (ADR 0100) is read off the controller's own moving bit during a signed
move (which moves the plate the same way under either convention), and the operator says
whether a larger position took the plate towards the sample. Every motion is asked for first
and runs under the rig's interlocks and Stop.
"""

from __future__ import annotations

import math

import numpy as np

from gelrig.bringup.common import Session, percent
from gelrig.bringup.operator import GAUGE_ERROR, TOWARD
from gelrig.drivers.kdc101.payloads import MOVING_FORWARD, MOVING_REVERSE
from gelrig.instrument.contracts.stage import (
    FORWARD_IS_NEGATIVE,
    FORWARD_IS_POSITIVE,
    StageConfig,
)
from gelrig.instrument.core.errors import GelrigError
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.rig import CompressionRig

#: APT time unit (s): velocity factor = counts/mm * T * 65536, acceleration factor =
#: counts/mm * T^2 * 65536 (Thorlabs' protocol document, instruments.md).
T_UNIT = 2048 / 6e6
#: Travel (m) of the scale fit, and its number of steps.
SCALE_TRAVEL = 5e-3
SCALE_STEPS = 10
#: The direction check's step (m) and when, after it starts, the status is read (s).
DIRECTION_STEP = 0.2e-3
DIRECTION_PEEK = 0.05
#: Overshoot (m) of the backlash check's approach from above, and its repeats.
BACKLASH_OVERSHOOT = 0.5e-3
BACKLASH_REPEATS = 5


class StageBringupError(GelrigError):
    """The stage is not as gelrig needs it (e.g. larger positions move away from the sample)."""


class StageBringup:
    """The stage's routines, in the order a bring-up runs them (:meth:`run`)."""

    def __init__(self, session: Session):
        rig = session.rig
        assert isinstance(rig, CompressionRig)
        self.s = session
        self.rig = rig
        self.config: StageConfig = rig.stage_caps
        self.start = self.config.min_position_m + 0.5e-3
        self.travel = min(SCALE_TRAVEL, self.config.max_position_m - self.start - 0.5e-3)
        #: the scale fitted by :meth:`scale` (counts/mm), used by :meth:`velocity`
        self.counts_per_mm: float | None = None

    def run(self) -> None:
        self.identify()
        if not self.home():
            return
        self.direction()
        self.scale()
        self.backlash()
        self.velocity()

    def _counts(self) -> float:
        return self.rig.stage.position() * 1e3 * self.config.counts_per_mm

    def _to(self, position: float) -> None:
        here = self.rig.stage.position()
        self.s.move(f"move to {position * 1e3:.3f} mm",
                    lambda: self.rig.stage.move_to(position, wait=False), toward=position > here)

    def identify(self) -> None:
        ident = self.rig.stage.identify()
        self.s.operator.say("KDC101: asked the controller who it is (no motion).")
        self.s.found(f"stage {ident.model} serial {ident.serial}, firmware {ident.firmware}")

    def home(self) -> bool:
        if not self.s.ask("stage.home", "KDC101: home the stage (the plate moves away from the "
                          "sample to the home switch). Take the sample off the plate first."):
            return False
        self.s.move("home", lambda: self.rig.stage.home(wait=False), toward=False)
        self.s.found(f"homed; position {self.rig.stage.position() * 1e3:.4f} mm")
        return True

    def direction(self) -> None:
        step = DIRECTION_STEP
        if not self.s.ask("stage.direction", f"KDC101 direction: rest the dial gauge on the "
                          f"plate; the plate moves {step * 1e3:g} mm to a larger position "
                          "(towards the sample) and the controller's moving bit is read."):
            return
        self._to(self.start)
        self.s.operator.zero_gauge()
        bits: list[int] = []

        def start() -> None:
            self.rig.stage.move_by(step, wait=False)
            self.rig.clock.sleep(DIRECTION_PEEK)
            bits.append(self.rig.stage.status().raw)

        self.s.move("direction step", start, toward=True)
        went = self.s.operator.plate_went()
        if went != TOWARD:
            raise StageBringupError(
                "a larger position moved the plate away from the sample: gelrig needs larger "
                "positions towards it (check the actuator's mounting); nothing written")
        raw = bits[0] if bits else 0
        if raw & MOVING_FORWARD and not raw & MOVING_REVERSE:
            word = FORWARD_IS_POSITIVE
        elif raw & MOVING_REVERSE and not raw & MOVING_FORWARD:
            word = FORWARD_IS_NEGATIVE
        else:
            self.s.found(f"direction: status 0x{raw:08X} during the move shows neither moving "
                         "bit alone; convention not confirmed")
            return
        was = "as the rig file says" if word == self.config.direction else \
            f"the rig file says {self.config.direction}: INVERTED"
        self.s.found(f"direction: {word} ({was}); status 0x{raw:08X} moving to larger counts")
        self.s.propose("stage", "direction", word,
                       f"signed move of +{step * 1e3:g} mm, status bit 0x{raw & 0x30:02X} while "
                       "moving; operator saw the plate go towards the sample", "exact")

    def scale(self) -> None:
        step = self.travel / SCALE_STEPS
        if not self.s.ask("stage.scale", f"KDC101 scale: with the dial gauge on the plate, "
                          f"the plate moves {SCALE_STEPS} steps of {step * 1e3:.3g} mm towards "
                          "the sample; read the gauge after each."):
            return
        self._to(self.start)
        self.s.operator.zero_gauge()
        counts, readings = [self._counts()], [0.0]
        for i in range(1, SCALE_STEPS + 1):
            self._to(self.start + i * step)
            counts.append(self._counts())
            readings.append(self.s.operator.gauge_reading())
        self._to(self.start)
        c, x = np.asarray(counts), np.asarray(readings) * 1e3  # counts, mm
        (slope, _), cov = np.polyfit(c, x, 1, cov=True)  # mm per count: the gauge is the noisy one
        cpm = 1.0 / slope
        u = float(np.sqrt(cov[0, 0])) / slope ** 2
        residual = float(np.max(np.abs(x - np.polyval(np.polyfit(c, x, 1), c)))) * 1e3
        self.counts_per_mm = float(cpm)
        believed = self.config.counts_per_mm
        self.s.found(f"scale: {cpm:.2f} +- {u:.2f} counts/mm ({percent(u, cpm)}); the rig "
                     f"file says {believed:g} ({(believed / cpm - 1) * 100:+.3f} %); largest "
                     f"residual {residual:.2f} um")
        method = (f"{SCALE_STEPS + 1} positions over {self.travel * 1e3:.3g} mm, dial gauge "
                  "readings fitted against encoder counts")
        self.s.propose("stage", "counts_per_mm", round(float(cpm), 2), method,
                       f"{u:.2g} counts/mm ({percent(u, cpm)}, k=1, fit residuals)")
        derived = "from counts_per_mm with the APT time unit 2048/6e6 s"
        self.s.propose("stage", "velocity_factor", round(float(cpm) * T_UNIT * 65536, 4),
                       derived, percent(u, cpm))
        self.s.propose("stage", "accel_factor", round(float(cpm) * T_UNIT ** 2 * 65536, 7),
                       derived, percent(u, cpm))

    def backlash(self) -> None:
        mid = self.start + self.travel / 2
        if not self.s.ask("stage.backlash", f"KDC101 backlash: the plate reaches "
                          f"{mid * 1e3:.3g} mm from below and from above "
                          f"({BACKLASH_REPEATS} times); read the gauge at each arrival."):
            return
        self._to(self.start)
        self.s.operator.zero_gauge()
        gaps = []
        for _ in range(BACKLASH_REPEATS):
            self._to(mid - BACKLASH_OVERSHOOT)
            self._to(mid)
            below = self.s.operator.gauge_reading()
            self._to(mid + BACKLASH_OVERSHOOT)
            self._to(mid)
            gaps.append(below - self.s.operator.gauge_reading())
        self._to(self.start)
        mean = float(np.mean(gaps))
        # the repeats' scatter, but never less than two gauge readings' error allows
        floor = GAUGE_ERROR * np.sqrt(2 / 3) / np.sqrt(len(gaps))
        spread = max(float(np.std(gaps, ddof=1) / np.sqrt(len(gaps))), float(floor))
        self.s.found(f"backlash: {mean * 1e6:.1f} +- {spread * 1e6:.1f} um (from below minus "
                     f"from above, {len(gaps)} repeats, gauge read to "
                     f"{GAUGE_ERROR * 1e6:g} um; Z825B spec < 8 um)")

    def velocity(self) -> None:
        v, a = self.config.max_velocity_m_s, self.config.acceleration_m_s2
        if not self.s.ask("stage.velocity", f"KDC101 velocity: the plate moves "
                          f"{self.travel * 1e3:.3g} mm at the rig file's max_velocity "
                          f"({v * 1e3:g} mm/s, {a * 1e3:g} mm/s^2); its speed is measured."):
            return
        self._to(self.start)
        samples: list[tuple[float, float]] = []
        self.rig.stage.set_velocity(v, a)
        self.s.move("velocity run", lambda: self.rig.stage.move_to(self.start + self.travel,
                                                                   wait=False),
                    toward=True, on_values=lambda values: samples.append(
                        (values.get("t_s", np.nan), values.get("position_m", np.nan))))
        self._to(self.start)
        t, z = (np.asarray(col) for col in zip(*samples, strict=True)) if samples else \
            (np.zeros(0), np.zeros(0))
        ramp = v * v / (2 * a)
        inside = (z > self.start + ramp + 0.1e-3) & (z < self.start + self.travel - ramp - 0.1e-3)
        if np.count_nonzero(inside) < 3:
            self.s.found("velocity: too few position reports at full speed to measure it")
            return
        speed = float(np.polyfit(t[inside], z[inside], 1)[0])  # believed m/s
        if self.counts_per_mm is not None:  # the rig file's scale -> the fitted one
            speed *= self.config.counts_per_mm / self.counts_per_mm
        self.s.found(f"velocity: {speed * 1e3:.4f} mm/s at full speed for {v * 1e3:g} mm/s "
                     f"requested ({(speed / v - 1) * 100:+.2f} %); cap reached")
        self.s.found(_acceleration_line(t, self.travel * speed / v, speed, a))


def _acceleration_line(t: FloatArray, travel: float, speed: float, asked: float) -> str:
    """The acceleration reached on one full-speed move, from how long the move lasted: a
    trapezoid over ``travel`` (m, true) at ``speed`` (m/s, measured) takes
    ``travel / speed + speed / a``; the move's start and end are known to the spacing of the
    samples that saw it moving, which bounds ``a`` (m/s^2) both ways."""
    if t.size < 2:
        return "acceleration: too few samples of the move to time it"
    step = float(np.median(np.diff(t)))
    lasted = float(t[-1] - t[0])
    bounds = [lasted + d - travel / speed for d in (step, -step)]  # time spent ramping
    if not bounds[0] > 0:
        return "acceleration: the move was too short to time its ramps"
    low = speed / bounds[0]
    high = speed / bounds[1] if bounds[1] > 0 else math.inf
    verdict = "reached" if low * 0.98 <= asked <= high * 1.02 else "NOT as requested"
    return (f"acceleration: {low * 1e3:.3g} to "
            f"{'inf' if math.isinf(high) else f'{high * 1e3:.3g}'} mm/s^2 from the move's "
            f"{lasted:.2f} s (+- {step:.2f} s) for {asked * 1e3:g} mm/s^2 requested; {verdict}")


__all__ = ["StageBringup", "StageBringupError"]
