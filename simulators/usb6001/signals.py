"""What the simulated USB-6001's inputs see: a voltage per channel for blocks of sample times.

A :class:`SignalSource` answers for consecutive blocks on the acquisition's sample grid
(``t_first + k dt``); it may keep state (contact history, filter, noise stream), so it is
queried in increasing time. The force signal of the compression rig is
:class:`LoadCellSignal`: plate-on-sphere force -> load-cell chain -> conditioner pole -> noise.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.scipy_ext import first_order
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.simulators.usb6001.config import DEFAULT_NOISE_RMS


@runtime_checkable
class SignalSource(Protocol):
    """Voltage (V) at one analog input for ``n`` samples at ``t_first + k dt`` (s)."""

    def volts(self, t_first: float, dt: float, n: int) -> FloatArray: ...


class ConstantSignal:
    """A fixed voltage plus seeded white noise: an unused input, or a reference."""

    def __init__(self, level: float = 0.0, noise_rms: float = 0.0, seed: int = 0):
        self.level = float(level)
        self.noise_rms = float(noise_rms)
        self._rng = np.random.default_rng(seed)

    def volts(self, t_first: float, dt: float, n: int) -> FloatArray:
        out = np.full(n, self.level)
        if self.noise_rms > 0:
            out += self.noise_rms * self._rng.standard_normal(n)
        return out


class SampleCounterSignal:
    """A test pattern: sample k on the clock's grid reads ``((k mod period) - period/2)`` codes.

    Decoding a record with :meth:`decode` gives k mod period per sample, so a reader can prove
    that no sample was lost or repeated. ``lsb`` must be the device's code size.
    """

    def __init__(self, lsb: float, period: int = 8000):
        if not 2 <= period <= 16000:
            raise ValueError(f"period must lie in [2, 16000] codes, got {period}")
        self.lsb = float(lsb)
        self.period = int(period)

    def volts(self, t_first: float, dt: float, n: int) -> FloatArray:
        k = round(t_first / dt) + np.arange(n)
        return np.asarray(((k % self.period) - self.period // 2) * self.lsb, dtype=float)

    def decode(self, volts: FloatArray) -> FloatArray:
        """Sample index modulo ``period`` for each value read."""
        return np.round(np.asarray(volts) / self.lsb) + self.period // 2


class LoadCellSignal:
    """Conditioner output for the plate-on-sphere force: the compression rig's force input.

    ``chain`` is the true chain of the simulated rig (its offset is what a tare must find);
    the conditioner's bandwidth acts as one pole, exact for a signal held over each sample
    interval; ``noise_rms`` (V) is seeded white noise added after it, with ``drift`` (V/s,
    from the first sample read) and ``correlated`` = (rms V, correlation time s): an
    Ornstein-Uhlenbeck process, exact at the sample times, drawn from its own seeded stream
    (so the white noise of a given seed does not change with it).
    """

    def __init__(
        self,
        contact: PlateSphereContact,
        chain: LoadCellChain,
        noise_rms: float = DEFAULT_NOISE_RMS,
        seed: int = 0,
        drift: float = 0.0,
        correlated: tuple[float, float] = (0.0, 1.0),
    ):
        if not (math.isfinite(noise_rms) and noise_rms >= 0):
            raise ValueError(f"noise_rms must be >= 0 V, got {noise_rms}")
        if not (math.isfinite(correlated[0]) and correlated[0] >= 0 and correlated[1] > 0):
            raise ValueError(f"correlated noise must be (rms >= 0 V, tau > 0 s), got "
                             f"{correlated}")
        self.contact = contact
        self.chain = chain
        self.noise_rms = float(noise_rms)
        self.drift = float(drift)
        self.correlated = (float(correlated[0]), float(correlated[1]))
        self._rng = np.random.default_rng(seed)
        self._ou_rng = np.random.default_rng([seed, 1])
        self._ou: float | None = None  # the correlated part at the last sample read ...
        self._ou_t = 0.0  # ... and that sample's time (s)
        self._t0: float | None = None
        self._state: float | None = None
        #: A dead weight on the cell (N, compressive positive): what a calibration mass adds
        #: to the contact's force from the next block read on (bring-up, issue 30).
        self.dead_load = 0.0

    def force(self, t_first: float, dt: float, n: int) -> FloatArray:
        """The true force (N) on the cell at the sample times (advances the contact), with
        any dead weight on it."""
        return self.contact.force_on_grid(t_first, dt, n) + self.dead_load

    def volts(self, t_first: float, dt: float, n: int) -> FloatArray:
        v = self.chain.volts(self.force(t_first, dt, n))
        if v.size == 0:
            return v
        a = math.exp(-2.0 * math.pi * self.chain.bandwidth * dt)
        if self._state is None:
            self._state = float(v[0])
        v = first_order(1.0 - a, 0.0, -a, v, a * self._state)
        self._state = float(v[-1])
        if self.noise_rms > 0:
            v += self.noise_rms * self._rng.standard_normal(v.size)
        return np.asarray(v + self._slow_noise(t_first, dt, v.size), dtype=float)

    def _slow_noise(self, t_first: float, dt: float, n: int) -> FloatArray | float:
        """The drift and the correlated part at the sample times (0.0 when neither is set)."""
        out: FloatArray | float = 0.0
        if self.drift:
            if self._t0 is None:
                self._t0 = t_first
            out = np.asarray(self.drift * (t_first - self._t0 + dt * np.arange(n)), dtype=float)
        rms, tau = self.correlated
        if rms > 0:
            a = math.exp(-dt / tau)
            if self._ou is None:  # the process starts in its stationary state
                self._ou = rms * float(self._ou_rng.standard_normal())
            elif t_first - dt > self._ou_t + 1e-9 * dt:  # a gap between reads: the process
                g = math.exp(-(t_first - dt - self._ou_t) / tau)  # went on meanwhile
                self._ou = g * self._ou + math.sqrt(1 - g * g) * rms * float(
                    self._ou_rng.standard_normal())
            z = rms * self._ou_rng.standard_normal(n)
            x = first_order(math.sqrt(1.0 - a * a), 0.0, -a, z, a * self._ou)
            self._ou = float(x[-1])
            self._ou_t = t_first + (n - 1) * dt
            out = out + x
        return out
