"""Small fakes of the instrument contracts, so step logic has fast unit tests.

They meet :class:`gelrig.instrument.contracts.stage.Stage`,
:class:`gelrig.instrument.contracts.loadcell.ForceSensor` and
:class:`gelrig.instrument.contracts.rheometer.Rheometer` in SI units on a :class:`VirtualClock`,
with the
least physics that makes a step's logic meaningful: a plate moving at constant speed into an
elastic Hertz sphere (no relaxation unless given), a rheometer arm sweeping an upper sphere
over a lower one with an elastic normal force and Coulomb friction. No wire, no thread, no
noise unless asked for. They record every command (``calls``) so a test can assert what a step
did, e.g. that motion was stopped. The HIL tests through the simulators stay the check of the
real drivers; these check the step logic in milliseconds.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from gelrig.instrument.contracts.loadcell import ForceBlock, LoadCellChain
from gelrig.instrument.contracts.rheometer import RheometerConfig, RheometerStatus, StreamPoint
from gelrig.instrument.contracts.stage import StageConfig, StageStatus
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import Disconnected, InstrumentTimeout, LimitError
from gelrig.instrument.core.identity import Identity
from gelrig.instrument.physics.contact import FloatArray, Material, hertz_prefactor
from gelrig.protocols.rig import CompressionLimits, CompressionRig, ShearLimits, ShearRig

#: Longest a frozen fake blocks a call (s, wall): every wait in the tests is bounded.
FREEZE_LIMIT = 30.0


class Faults:
    """What a test makes a fake do wrong: ``freeze()`` makes every call block (as a frozen
    server does) until ``thaw()`` or :data:`FREEZE_LIMIT`; ``unreachable`` makes every call
    raise Disconnected; ``fail_stop`` makes only the stop raise; ``fail_at`` makes calls raise
    Disconnected from that clock time on; ``freeze_at`` freezes the first call at or after
    that clock time."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.unreachable = False
        self.fail_stop = False
        self.fail_at: float | None = None
        self.freeze_at: float | None = None
        self.frozen = threading.Event()
        self.blocked = threading.Event()  # set while a call is blocked by a freeze
        self._thawed = threading.Event()

    def freeze(self) -> None:
        self._thawed.clear()
        self.frozen.set()

    def thaw(self) -> None:
        self.frozen.clear()
        self._thawed.set()

    def gate(self, now: float, stop: bool = False) -> None:
        """Called first by every call of the fake."""
        if self.freeze_at is not None and now >= self.freeze_at:
            self.freeze_at = None
            self.freeze()
        if self.frozen.is_set():
            self.blocked.set()
            self._thawed.wait(FREEZE_LIMIT)
            self.blocked.clear()
        if self.unreachable or (stop and self.fail_stop) or (
                self.fail_at is not None and now >= self.fail_at):
            raise Disconnected(f"{self.name}: link lost")


@dataclass
class _Leg:
    """A constant-speed move from ``z0`` at ``t0`` to ``z1`` (no ramps: a fake)."""

    t0: float
    z0: float
    z1: float
    speed: float

    @property
    def t1(self) -> float:
        return self.t0 + abs(self.z1 - self.z0) / self.speed

    def at(self, t: ArrayLike) -> FloatArray:
        t = np.asarray(t, dtype=float)
        frac = np.clip((t - self.t0) / max(self.t1 - self.t0, 1e-300), 0.0, 1.0)
        return self.z0 + (self.z1 - self.z0) * frac


class FakeStage:
    """A stage that moves at its set velocity, instantly up to speed."""

    def __init__(self, clock: VirtualClock, config: StageConfig | None = None,
                 position: float = 0.0, homed: bool = False):
        self.clock = clock
        self.config = config or StageConfig()
        self.homed = homed
        self.velocity = 1e-3
        self.calls: list[str] = []
        self.faults = Faults("fake stage")
        self._legs: list[_Leg] = [_Leg(-1.0, position, position, 1.0)]

    # the contract
    def identify(self) -> Identity:
        return Identity("tests", "fake stage", "1")

    def enable(self) -> None:
        self.calls.append("enable")

    def home(self, wait: bool = True, timeout: float | None = None) -> None:
        self.faults.gate(self.clock.now())
        self.calls.append("home")
        self._go(0.0)
        if wait:
            self.wait_until_stopped(timeout)
        self.homed = True

    def set_velocity(self, max_m_s: float, accel_m_s2: float) -> None:
        self.faults.gate(self.clock.now())
        self.config.check_velocity(max_m_s, accel_m_s2)
        if max_m_s > self.config.max_velocity_m_s:
            raise LimitError(f"velocity {max_m_s * 1e3:g} mm/s above the stage's cap")
        self.velocity = max_m_s

    def move_to(self, position_m: float, wait: bool = True, timeout: float | None = None) -> None:
        self.faults.gate(self.clock.now())
        self.config.check_position(position_m)
        self.calls.append(f"move_to {position_m:.6g}")
        self._go(position_m)
        if wait:
            self.wait_until_stopped(timeout)

    def move_by(self, distance_m: float, wait: bool = True, timeout: float | None = None) -> None:
        self.move_to(self.position() + distance_m, wait, timeout)

    def move_velocity(self, direction: int) -> None:
        end = self.config.max_position_m if direction > 0 else self.config.min_position_m
        self._go(end)

    def keep_alive(self) -> None:
        """Nothing to renew: the fake's moves are not segmented (ADR 0201)."""
        self.faults.gate(self.clock.now())

    def stop(self, immediate: bool = True) -> None:
        self.faults.gate(self.clock.now(), stop=True)
        self.calls.append("stop")
        self._go(self.position())

    def position(self) -> float:
        self.faults.gate(self.clock.now())
        return float(self.positions_at(self.clock.now()))

    def status(self) -> StageStatus:
        moving = self.is_moving()
        return StageStatus(0, moving, False, self.homed, True, True, False, False, False, False)

    def is_moving(self) -> bool:
        self.faults.gate(self.clock.now())
        return self.clock.now() < self._legs[-1].t1

    def wait_until_stopped(self, timeout: float | None = None) -> None:
        remaining = self._legs[-1].t1 - self.clock.now()
        if timeout is not None and remaining > timeout:
            self.clock.sleep(timeout)
            self.stop()
            raise InstrumentTimeout("fake stage: move did not end in time")
        if remaining > 0:
            self.clock.sleep(remaining)

    def close(self) -> None:
        self.calls.append("close")

    # for the force sensor
    def positions_at(self, t: ArrayLike) -> FloatArray:
        """Plate position at clock times ``t`` (the leg in force at each time)."""
        t = np.asarray(t, dtype=float)
        out = np.empty_like(t)
        starts = np.array([leg.t0 for leg in self._legs])
        which = np.searchsorted(starts, t, side="right") - 1
        for i in np.unique(which):
            mask = which == i
            out[mask] = self._legs[max(int(i), 0)].at(t[mask])
        return out

    def _go(self, target: float) -> None:
        self.faults.gate(self.clock.now())
        now = self.clock.now()
        here = float(self.positions_at(now))
        self._legs.append(_Leg(now, here, target, self.velocity))


class FakeForceSensor:
    """Samples the Hertz force of an elastic (or relaxing) sphere under the fake plate.

    The contact is Hertz with the plate's overlap past ``first_touch`` and the modulus
    ``material`` relaxes from the moment of contact (a coarse stand-in for the hereditary
    integral: enough for a fit to see relaxation, not a model of it). Reads wait on the clock
    for their samples, as a hardware-timed acquisition does.
    """

    def __init__(self, clock: VirtualClock, stage: FakeStage, first_touch: float = 6.2e-3,
                 radius: float = 9.315e-3, material: Material | None = None,
                 noise: float = 0.0, chain: LoadCellChain | None = None, seed: int = 0):
        self.clock = clock
        self.stage = stage
        self.first_touch = first_touch
        self.radius = radius
        self.material = material or Material.of(7146.0)
        self.noise = noise
        self.chain = chain or LoadCellChain()
        self.rng = np.random.default_rng(seed)
        self.zero = self.chain.offset
        self.calls: list[str] = []
        self.faults = Faults("fake force sensor")
        self._rate = 0.0
        self._next = 0  # index of the next sample to read
        self._t0 = 0.0
        self._touched_at: float | None = None

    @property
    def rate(self) -> float:
        return self._rate

    def identify(self) -> Identity:
        return Identity("tests", "fake force sensor", "1")

    def start(self, rate_hz: float) -> None:
        self.calls.append(f"start {rate_hz:g}")
        self._rate = rate_hz
        self._t0 = self.clock.now()
        self._next = 0

    def force_at(self, t: FloatArray) -> FloatArray:
        delta = np.maximum(self.stage.positions_at(t) - self.first_touch, 0.0)
        touching = delta > 0
        if touching.any() and self._touched_at is None:
            self._touched_at = float(t[np.argmax(touching)])
        age = t - (self._touched_at if self._touched_at is not None else t[0])
        modulus = self.material.modulus(np.maximum(age, 0.0))
        c = hertz_prefactor(self.radius, self.material.nu)
        return c * modulus * delta**1.5

    def read_block(self, n: int | None = None, timeout: float | None = None) -> ForceBlock:
        self.faults.gate(self.clock.now())
        if self._rate <= 0:
            raise InstrumentTimeout("fake force sensor: not started")
        available = math.floor((self.clock.now() - self._t0) * self._rate)
        if n is None:
            n = max(available - self._next, 0)
        wait = (self._next + n) / self._rate + self._t0 - self.clock.now()
        if wait > 0:
            self.clock.sleep(wait)
        t = self._t0 + (self._next + np.arange(1, n + 1)) / self._rate
        self._next += n
        force = self.force_at(t) + self.noise * self.rng.standard_normal(n)
        volts = self.chain.volts(force)
        return ForceBlock(t, self.chain.newtons(volts, self.zero), volts, np.zeros(n, bool))

    def tare(self, duration: float = 1.0) -> float:
        block = self.read_block(max(1, round(duration * self._rate)))
        return self.zero_on(block.volts)

    def zero_on(self, volts: ArrayLike) -> float:
        before = self.zero
        self.zero = float(np.mean(np.asarray(volts, dtype=float)))
        return (self.zero - before) / self.chain.sensitivity

    def stop(self) -> None:
        self.calls.append("stop")
        self._rate = 0.0

    def close(self) -> None:
        self.calls.append("close")


def compression_rig(first_touch: float = 6.2e-3, material: Material | None = None,
                    limits: CompressionLimits | None = None, noise: float = 0.0
                    ) -> tuple[CompressionRig, FakeStage, FakeForceSensor]:
    """A compression rig of fakes on a virtual clock; returns the rig and both fakes."""
    clock = VirtualClock()
    stage = FakeStage(clock)
    force = FakeForceSensor(clock, stage, first_touch, material=material, noise=noise)
    rig = CompressionRig(stage, force, clock, limits or CompressionLimits(), simulated=True)
    return rig, stage, force


@dataclass
class FakeRheometer:
    """An arm carrying the upper sphere over a fixed lower one (elastic, Coulomb friction).

    The spheres overlap where the arc distance between their centres, at the vertical
    separation set by the gap, is below ``r1 + r2``; the normal force is Hertz with a constant
    modulus, the torque is ``mu * N * arm`` against the motion plus the geometric share of N.
    """

    clock: VirtualClock
    config: RheometerConfig = field(default_factory=RheometerConfig)
    r1: float = 9.2e-3
    r2: float = 9.96e-3
    touch_gap: float = 3e-3
    lower_angle: float = 0.8
    g: float = 4e3
    mu: float = 5e-3
    calls: list[str] = field(default_factory=list)
    faults: Faults = field(default_factory=lambda: Faults("fake rheometer"))
    _gap: float = 10e-3
    _referenced: bool = False
    _speed: float = 0.0
    _t: float = 0.0
    _angle: float = 0.0
    _stream: float | None = None
    _last_point: float = 0.0
    _points: list[StreamPoint] = field(default_factory=list)

    def identify(self) -> Identity:
        return Identity("tests", "fake rheometer", "1")

    def _advance(self, stop: bool = False) -> None:
        """Bring the arm to the clock's time, streaming points on the way (every state change
        calls this first, so the points see the state that held when they were taken)."""
        now = self.clock.now()
        self.faults.gate(now, stop)
        omega = self._speed / self.config.arm
        while self._stream is not None and self._last_point + self._stream <= now:
            self._last_point += self._stream
            angle = self._angle + omega * (self._last_point - self._t)
            torque, normal = self._forces(angle)
            self._points.append(StreamPoint(self._last_point, angle, angle * self.config.arm,
                                            torque, normal, self._gap))
        self._angle += omega * (now - self._t)
        self._t = now

    def status(self) -> RheometerStatus:
        self._advance()
        mode = "rotating" if self._speed else "idle"
        return RheometerStatus(mode, False, self._referenced, self._stream is not None, False,
                               False, False)

    def zero_gap(self) -> None:
        self.calls.append("zero_gap")
        self._referenced = True

    def set_gap(self, gap: float, wait: bool = True) -> None:
        if not self._referenced:
            raise LimitError("gap moves need a zero_gap first")
        if not self.config.gap_min <= gap <= self.config.gap_max:
            raise LimitError(f"gap {gap * 1e3:g} mm outside the rig's range")
        self._advance()
        self.calls.append(f"set_gap {gap:.6g}")
        self._gap = gap

    def gap(self) -> float:
        self.faults.gate(self.clock.now())
        return self._gap

    def rotate(self, speed: float) -> None:
        if not self.config.speed_allowed(speed):
            raise LimitError(f"speed {speed * 1e3:g} mm/s above the rig's maximum")
        self._advance()
        self.calls.append(f"rotate {speed:.6g}")
        self._speed = speed

    def stop(self) -> None:
        self._advance(stop=True)
        self.calls.append("stop")
        self._speed = 0.0

    def hold(self) -> None:
        self.stop()

    def keep_alive(self) -> None:
        """Nothing to renew: the fake's rotations are not time-limited (ADR 0201)."""
        self._advance()

    def angle(self) -> float:
        self._advance()
        return self._angle

    def theta(self) -> float:
        return self.angle() * self.config.arm

    def _forces(self, angle: float) -> tuple[float, float]:
        """(torque, normal force) at ``angle`` and the current gap and speed."""
        h = self.r1 + self.r2 - (self.touch_gap - self._gap)
        psi = (self.lower_angle - angle) * self.config.arm
        d = math.hypot(psi, h)
        delta = self.r1 + self.r2 - d
        if delta <= 0:
            return 0.0, 0.0
        radius = self.r1 * self.r2 / (self.r1 + self.r2)
        f = hertz_prefactor(radius) * self.g * delta**1.5
        vertical, horizontal = f * h / d, f * psi / d
        sign = math.copysign(1.0, self._speed) if self._speed else 0.0
        tangential = -horizontal + sign * self.mu * vertical
        return tangential * self.config.arm, vertical

    def torque(self) -> float:
        return self._forces(self.angle())[0]

    def normal_force(self) -> float:
        return self._forces(self.angle())[1]

    def start_stream(self, interval: float) -> None:
        self._advance()
        self._points = []
        self._stream = interval
        self._last_point = self.clock.now()

    def read_stream(self) -> list[StreamPoint]:
        self._advance()
        points, self._points = self._points, []
        return points

    def stop_stream(self) -> None:
        self._advance()
        self._stream = None

    def close(self) -> None:
        self.stop()
        self.calls.append("close")


def shear_rig(limits: ShearLimits | None = None, **kwargs: float
              ) -> tuple[ShearRig, FakeRheometer]:
    """A shear rig of a fake rheometer on a virtual clock."""
    clock = VirtualClock()
    rheo = FakeRheometer(clock, **kwargs)  # type: ignore[arg-type]
    return ShearRig(rheo, clock, limits or ShearLimits(), simulated=True), rheo
