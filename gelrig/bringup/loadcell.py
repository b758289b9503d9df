"""Load-cell bring-up: zero and noise, calibration with known masses, rated output and gain.

The chain (load cell -> conditioner -> USB-6001) is measured in volts at the input, so
nothing depends on the rig file's belief about it: the unloaded signal gives the zero, the
noise (rms with the quantiser's q^2/12 removed, its drift and spectrum) and the quantisation
step; masses the operator puts on the cell give the sensitivity (V/N) and offset by a straight
line fit, with a linearity check against the cell's +-0.1 % of rated output; the rated output
follows from the sensitivity and the conditioner's gain as the operator reads it off the
device. The noise in newtons uses the measured sensitivity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gelrig.bringup.common import Session, percent
from gelrig.bringup.noise_model import (
    BLOCK,
    Correlated,
    correlated_part,
    drift_uncertainty,
)
from gelrig.bringup.operator import GRAVITY, MASS_TOLERANCE
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.core.errors import GelrigError
from gelrig.protocols.rig import CompressionRig
from gelrig.protocols.rigfile import CompressionRigSpec

#: Sample rate (Hz) and length (s) of the unloaded record.
NOISE_RATE = 1000.0
NOISE_SECONDS = 20.0
#: Per calibration point: settling time discarded, then the averaged record (s).
SETTLE, AVERAGE = 0.5, 2.0
#: Marked masses (kg) a calibration set is drawn from (1-2-5 steps).
MASS_SET = tuple(m * 1e-3 for m in (5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000))
#: Masses used: those between these fractions of the cell's capacity.
LOAD_RANGE = (0.05, 0.8)
#: The Futek LSB200's nonlinearity (fraction of rated output).
NONLINEARITY = 1e-3


@dataclass(frozen=True)
class Noise:
    """The unloaded signal, in volts at the input."""

    zero: float  # mean (V)
    rms: float  # white noise, detrended, quantisation removed (V)
    raw_rms: float  # detrended, as read (V)
    drift: float  # V/s over the record
    step: float  # quantisation step (V)
    low_band: float  # PSD below 1 Hz over the median PSD (1: white)
    n: int
    #: the Ornstein-Uhlenbeck part (V), None when not resolved; ``rms`` excludes it
    correlated: Correlated | None = None


def acquire(rig: CompressionRig, seconds: float, rate: float = NOISE_RATE) -> np.ndarray:
    """``seconds`` of input volts at ``rate``, read in 1 s blocks (the acquisition restarted
    for it and stopped after)."""
    rig.end_monitoring()
    rig.force.stop()
    rig.force.start(rate)
    try:
        n = round(seconds * rate)
        per = int(rate)
        parts = [rig.force.read_block(min(per, n - i)).volts for i in range(0, n, per)]
    finally:
        rig.force.stop()
    return np.concatenate(parts) if parts else np.zeros(0)


def analyse_noise(volts: np.ndarray, rate: float) -> Noise:
    """Zero, noise (white, drift, correlated part), quantisation step and spectrum shape of
    an unloaded record."""
    from scipy.signal import welch

    t = np.arange(volts.size) / rate
    drift, intercept = np.polyfit(t, volts, 1)
    rest = volts - (intercept + drift * t)
    raw = float(np.std(rest))
    levels = np.diff(np.unique(volts))
    step = float(levels[levels > 1e-9].min()) if np.any(levels > 1e-9) else 0.0
    part = correlated_part(rest, rate)
    slow = part.rms ** 2 if part is not None else 0.0
    rms = float(np.sqrt(max(raw ** 2 - step ** 2 / 12.0 - slow, 0.0)))
    f, psd = welch(rest, fs=rate, nperseg=min(volts.size, 4096))
    low = psd[(f > 0) & (f < 1.0)]
    ratio = float(np.mean(low) / np.median(psd[f > 0])) if low.size else float("nan")
    return Noise(float(np.mean(volts)), rms, raw, float(drift), step, ratio, int(volts.size),
                 part)


def calibration_masses(chain: LoadCellChain) -> list[float]:
    """The marked masses (kg) to put on a cell of ``chain.capacity``."""
    lo, hi = (f * chain.capacity / GRAVITY for f in LOAD_RANGE)
    return [m for m in MASS_SET if lo <= m <= hi]


class LoadCellBringup:
    """The load cell's routines: :meth:`zero_and_noise`, then :meth:`calibrate`."""

    def __init__(self, session: Session):
        rig = session.rig
        assert isinstance(rig, CompressionRig)
        self.s = session
        self.rig = rig
        spec = session.spec
        if not isinstance(spec, CompressionRigSpec):
            raise GelrigError("load-cell bring-up needs the rig file's [force.chain]")
        self.chain: LoadCellChain = spec.force.chain
        self.noise: Noise | None = None
        self.sensitivity: tuple[float, float] | None = None  # V/N and its u

    def run(self) -> None:
        self.zero_and_noise()
        self.calibrate()
        self.noise_in_newtons()

    def zero_and_noise(self) -> None:
        if not self.s.ask("loadcell.noise", f"Load cell zero and noise: nothing on the cell; "
                          f"{NOISE_SECONDS:g} s of the unloaded signal are recorded at "
                          f"{NOISE_RATE:g} Hz (no motion)."):
            return
        self.s.operator.unload()
        noise = analyse_noise(acquire(self.rig, NOISE_SECONDS), NOISE_RATE)
        self.noise = noise
        self.s.found(f"zero {noise.zero * 1e3:.3f} mV; noise {noise.rms * 1e3:.4f} mV rms "
                     f"({noise.raw_rms * 1e3:.4f} mV as read, quantisation step "
                     f"{noise.step * 1e3:.4f} mV); drift {noise.drift * 1e6:.3g} uV/s; "
                     f"spectrum below 1 Hz at {noise.low_band:.2f}x the median (1: white)")
        self.s.propose("force.chain", "offset", f"{noise.zero * 1e3:.4f} mV",
                       f"mean of {NOISE_SECONDS:g} s unloaded at {NOISE_RATE:g} Hz "
                       "(a run still tares)",
                       f"{noise.raw_rms / np.sqrt(noise.n) * 1e3:.2g} mV")

    def calibrate(self) -> None:
        masses = calibration_masses(self.chain)
        listed = ", ".join(f"{m * 1e3:g} g" for m in masses)
        if not self.s.ask("loadcell.calibration", f"Load cell calibration: put each mass on "
                          f"the cell in turn ({listed}) and enter its marked mass; the input "
                          f"is averaged {AVERAGE:g} s for each (no motion)."):
            return
        loads, volts = [0.0], [self._mean()]
        for nominal in masses:
            marked = self.s.operator.load_mass(nominal)
            loads.append(marked * GRAVITY)
            volts.append(self._mean())
        self.s.operator.unload()
        back = self._mean()
        f, v = np.asarray(loads), np.asarray(volts)
        (s, v0), cov = np.polyfit(f, v, 1, cov=True)
        u_fit = float(np.sqrt(cov[0, 0]))
        u = float(np.hypot(u_fit, s * MASS_TOLERANCE / np.sqrt(3)))
        full = s * self.chain.capacity
        worst = float(np.max(np.abs(v - (v0 + s * f)))) / full
        ok = worst <= NONLINEARITY + MASS_TOLERANCE
        self.sensitivity = (float(s), u)
        believed = self.chain.sensitivity
        self.s.found(f"sensitivity {s:.5g} +- {u:.2g} V/N ({percent(u, s)}); the rig file's "
                     f"chain gives {believed:.5g} ({(believed / s - 1) * 100:+.2f} %); "
                     f"linearity: largest residual {worst * 100:.3f} % of full scale "
                     f"({'within' if ok else 'OUTSIDE'} the cell's 0.1 % plus the masses' "
                     f"0.1 %); back at zero {(back - v0) / s * 1e3:+.3f} mN")
        gain = self.s.operator.conditioner_gain(self.chain.gain)
        rated = s * self.chain.capacity / (self.chain.excitation * gain)
        u_rated = rated * u / s
        self.s.found(f"rated output {rated * 1e3:.4f} +- {u_rated * 1e3:.2g} mV/V at gain "
                     f"{gain:g}; the rig file says {self.chain.rated_output * 1e3:g} mV/V")
        method = (f"{len(masses)} masses + zero ({listed}, marked to 0.1 %, g = {GRAVITY} "
                  f"m/s^2), line fit of input volts; gain {gain:g} as set on the conditioner")
        self.s.propose("force.chain", "gain", float(gain), "read off the conditioner by the "
                       "operator; the product with rated_output is the calibration's",
                       "as set")
        self.s.propose("force.chain", "rated_output", f"{rated * 1e3:.5g} mV/V", method,
                       f"{u_rated * 1e3:.2g} mV/V ({percent(u_rated, rated)}, k=1)")
        if not ok:
            self.s.operator.say("  the calibration is not linear within the cell's spec: "
                                "check the masses and the mounting before trusting it")

    def noise_in_newtons(self) -> None:
        if self.noise is None:
            return
        if self.sensitivity is not None:
            s, u_s = self.sensitivity
            how = "measured sensitivity"
        else:
            s, u_s = self.chain.sensitivity, 0.0
            how = "the rig file's sensitivity (not calibrated)"
        n = self.noise
        rms = n.rms / s
        u = rms * float(np.hypot(1 / np.sqrt(2 * n.n), u_s / s))
        part = n.correlated
        if part is not None and rms > 0:  # the white part is what the correlated leaves
            u = float(np.hypot(u, (part.rms / s) ** 2 * part.u_rms / rms))
        self.s.found(f"force noise {rms * 1e3:.4f} mN rms white through the {how}; drift "
                     f"{n.drift / s * 1e6:.3g} uN/s; quantisation step {n.step / s * 1e3:.4f} mN; "
                     + (f"correlated part {part.rms / s * 1e3:.4f} mN rms, {part.tau * 1e3:.3g} ms"
                        if part else "no correlated part resolved"))
        record = f"{NOISE_SECONDS:g} s unloaded at {NOISE_RATE:g} Hz"
        self.s.propose("force.chain", "noise", f"{rms * 1e3:.4g} mN",
                       f"white rms of {record}, detrended, q^2/12 "
                       f"{'and the correlated part ' if part else ''}removed "
                       f"(q = {n.step / s * 1e3:.3g} mN), through the {how}; PSD below 1 Hz "
                       f"{n.low_band:.2f}x median",
                       f"{u * 1e3:.2g} mN ({percent(u, rms)}, k=1)")
        u_drift = drift_uncertainty(n.rms, part, NOISE_RATE, NOISE_SECONDS) / s
        self.s.propose("force.chain", "noise_drift", f"{n.drift / s * 1e6:.4g} uN/s",
                       f"slope of a line fitted to {record}, through the {how}",
                       f"{u_drift * 1e6:.2g} uN/s (k=1)")
        if part is None:
            return
        self.s.propose("force.chain", "noise_correlated", f"{part.rms / s * 1e3:.4g} mN",
                       f"exponential fitted to the autocovariance of {record} in "
                       f"{BLOCK * 1e3:g} ms means, through the {how}",
                       f"{part.u_rms * 100:.2g} % (k=1, from the record's length)")
        self.s.propose("force.chain", "noise_tau", f"{part.tau * 1e3:.4g} ms",
                       "the same fit's correlation time", f"{part.u_tau * 100:.2g} % (k=1, "
                       "from the record's length)")

    def _mean(self) -> float:
        volts = acquire(self.rig, SETTLE + AVERAGE)
        return float(np.mean(volts[int(SETTLE * NOISE_RATE):]))


__all__ = ["LoadCellBringup", "Noise", "acquire", "analyse_noise", "calibration_masses"]
