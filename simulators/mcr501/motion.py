"""Closed-form motion of the arm and the lift, so any instant can be evaluated lazily.

The arm ramps at constant angular acceleration to its set speed, then turns uniformly; the
lift travels at constant speed to its set gap. Each command replaces the profile from the
time it arrives; the profiles are immutable values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Spin:
    """Arm angle from ``t0``: speed ``omega0`` ramps to ``target`` (rad/s) at ``accel``."""

    t0: float
    phi0: float
    omega0: float
    target: float
    accel: float

    @property
    def ramp_end(self) -> float:
        """Time the set speed is reached."""
        return self.t0 + abs(self.target - self.omega0) / self.accel

    def at(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Angle (rad) and angular speed (rad/s) at times ``t >= t0``."""
        a = math.copysign(self.accel, self.target - self.omega0)
        ramp = self.ramp_end - self.t0
        tau = np.asarray(t, dtype=float) - self.t0
        tr = np.minimum(tau, ramp)
        phi = self.phi0 + self.omega0 * tr + 0.5 * a * tr * tr + self.target * (tau - tr)
        omega = np.where(tau < ramp, self.omega0 + a * tr, self.target)
        return phi, omega

    def state(self, t: float) -> tuple[float, float]:
        """:meth:`at` for one instant, in plain floats (the same operations in the same order,
        so the same result to the last bit, without numpy's per-call cost)."""
        a = math.copysign(self.accel, self.target - self.omega0)
        ramp = self.ramp_end - self.t0
        tau = float(t) - self.t0
        tr = tau if tau <= ramp else ramp  # np.minimum
        phi = self.phi0 + self.omega0 * tr + 0.5 * a * tr * tr + self.target * (tau - tr)
        omega = self.omega0 + a * tr if tau < ramp else self.target
        return phi, omega

    def command(self, t: float, target: float) -> Spin:
        """The profile after a new set speed at ``t``."""
        phi, omega = self.state(t)
        return Spin(t, phi, omega, target, self.accel)

    def halt(self, t: float) -> Spin:
        """Stopped dead at ``t`` (an instrument trip)."""
        phi, _ = self.state(t)
        return Spin(t, phi, 0.0, 0.0, self.accel)

    def peak_speed(self, t1: float, t2: float) -> float:
        """Largest |omega| over [t1, t2] (the speed is monotonic between breakpoints)."""
        return max(abs(self.state(t1)[1]), abs(self.state(t2)[1]))


@dataclass(frozen=True)
class Lift:
    """Gap from ``t0``: from ``z0`` towards ``target`` (m) at ``speed`` (m/s)."""

    t0: float
    z0: float
    target: float
    speed: float

    @property
    def end(self) -> float:
        """Time the lift arrives."""
        return self.t0 + abs(self.target - self.z0) / self.speed

    def at(self, t: FloatArray) -> FloatArray:
        """Gap (m) at times ``t >= t0``."""
        tau = np.minimum(np.asarray(t, dtype=float) - self.t0, self.end - self.t0)
        return self.z0 + math.copysign(self.speed, self.target - self.z0) * tau

    def gap(self, t: float) -> float:
        """:meth:`at` for one instant, in plain floats (same operations, same result)."""
        tau = float(t) - self.t0
        span = self.end - self.t0
        if not tau <= span:  # np.minimum
            tau = span
        return self.z0 + math.copysign(self.speed, self.target - self.z0) * tau

    def moving(self, t: float) -> bool:
        return t < self.end

    def command(self, t: float, target: float) -> Lift:
        return Lift(t, self.gap(t), target, self.speed)

    def halt(self, t: float) -> Lift:
        z = self.gap(t)
        return Lift(t, z, z, self.speed)

    def rate(self, t1: float, t2: float) -> float:
        """Lift speed (m/s) if it moves during [t1, t2], else 0."""
        return self.speed if t1 < self.end and self.target != self.z0 else 0.0
