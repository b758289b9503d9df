"""One time base per run: how an instrument's own time maps onto the run's clock (issue 24).

Every recorded sample carries a time on the run's clock. A hardware-timed acquisition
(the USB-6001) samples on its own crystal, which drifts from the host's clock by tens of ppm,
and delivers its samples in USB transfers with a latency: :class:`SampleClock` maps sample k
to ``t0 + k / rate + slope * k`` where ``t0`` is the middle of the window in which the start
was commanded (its half-width the start's uncertainty) and ``slope`` (the drift) is the
slope of the lower envelope of the blocks' arrivals (a block cannot arrive before its last
sample was taken; the earliest arrivals, binned over the run, fall on a line whose slope is
the drift whatever the latency). :class:`PeriodicArrivals` narrows the moments of messages
an instrument sends by itself at a regular period (the KDC101's status updates) from their
arrival windows. :class:`TimeMapping` is what run.json says of one instrument's mapping.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gelrig.instrument.core.scipy_ext import siegel_slope

FloatArray = NDArray[np.float64]

#: Seconds of samples per bin of the arrivals' lower envelope.
DRIFT_BIN_S = 5.0
#: Bins kept (the latest 40 minutes): a week-long run keeps a bounded envelope.
KEEP_BINS = 500
#: Bins the drift is fitted on at most (repeated medians cost the square of their number).
FIT_BINS = 48
#: Largest drift believed (ppm): the USB-6001's timebase is specified to +-100 ppm
#: (UNVERIFIED); an estimate beyond this is clipped.
MAX_DRIFT_PPM = 300.0
#: Bins needed before the drift is estimated (until then it is taken as 0).
DRIFT_MIN_BINS = 3


@dataclass(frozen=True)
class TimeMapping:
    """How one instrument's readings are put on the run's clock, and how well (run.json)."""

    instrument: str
    method: str
    uncertainty_s: float
    details: dict[str, Any]

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["uncertainty_s"] = _finite(self.uncertainty_s)
        return out


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


class SampleClock:
    """Run-clock times of a hardware-timed acquisition's samples.

    ``rate`` (Hz) is the nominal sample rate; the start was commanded between ``lo`` and
    ``hi`` (run clock, s). :meth:`arrived` takes each block's arrival (its last sample's index
    and the run-clock time the read returned); :meth:`times` maps sample indices to times.
    """

    def __init__(self, rate: float, lo: float, hi: float, bin_s: float = DRIFT_BIN_S):
        self.rate = float(rate)
        self.t0 = 0.5 * (lo + hi)
        self.start_uncertainty = 0.5 * (hi - lo)
        self.bin = max(1, round(bin_s * rate))
        self._mins: dict[int, tuple[float, float]] = {}  # bin -> (index, earliest offset)
        self._slope = 0.0
        self._arrivals = 0
        self._last = -math.inf

    def arrived(self, last_index: int, t: float) -> None:
        """Sample ``last_index`` had arrived by run-clock time ``t``."""
        if last_index < 0:
            return
        self._arrivals += 1
        u = t - last_index / self.rate
        b = last_index // self.bin
        best = self._mins.get(b)
        new_bin = b not in self._mins and bool(self._mins) and b > max(self._mins)
        if best is None or u < best[1]:
            self._mins[b] = (float(last_index), u)
        if new_bin:  # a bin is complete: refit the envelope over the complete bins
            if len(self._mins) > KEEP_BINS:
                del self._mins[min(self._mins)]
            full = [v for k, v in self._mins.items() if k < b]
            if len(full) > FIT_BINS:  # evenly over the kept span: the fit's cost is bounded
                full = [full[i] for i in np.linspace(0, len(full) - 1, FIT_BINS).astype(int)]
            if len(full) >= DRIFT_MIN_BINS:
                idx = np.array([v[0] for v in full])
                off = np.array([v[1] for v in full])
                # repeated medians: a bin whose earliest arrival was late (no read waited in
                # it) does not tilt the line
                slope = siegel_slope(off, idx)
                limit = MAX_DRIFT_PPM * 1e-6 / self.rate
                self._slope = min(max(slope, -limit), limit)

    def times(self, k: FloatArray) -> FloatArray:
        """Run-clock times (s) of consecutive samples ``k``, increasing across calls: where a
        new drift estimate moves the line back, the times slew (at half a sample period)
        onto it instead of jumping."""
        k = np.asarray(k, dtype=float)
        out: FloatArray = self.t0 + k * (1.0 / self.rate + self._slope)
        if out.size:
            least = self._last + 0.5 / self.rate * np.arange(1, out.size + 1)
            out = np.maximum(out, least)
            self._last = float(out[-1])
        return out

    @property
    def drift_ppm(self) -> float:
        """The device's sample clock against the run's, estimated (ppm; + runs fast)."""
        return -self._slope * self.rate * 1e6

    def mapping(self, instrument: str) -> TimeMapping:
        """What run.json says of this mapping."""
        return TimeMapping(
            instrument, "sample clock: t = t0 + k / rate, corrected for the drift estimated "
            "from the earliest block arrivals", self.start_uncertainty,
            {"t0_s": self.t0, "rate_hz": self.rate, "drift_ppm": self.drift_ppm,
             "start_uncertainty_s": self.start_uncertainty, "blocks": self._arrivals,
             "drift_estimated": len(self._mins) > DRIFT_MIN_BINS})


class PeriodicArrivals:
    """When each message of a periodic stream was sent, from the windows it arrived in.

    Message k of a stream was sent at ``t0 + k * period`` for an unknown ``t0``; each is known
    only to have been sent in a window ``[lo, hi]`` (after the input was last found empty, less
    the link's latency; before the read that brought it). The host reads when it has other
    work, so a window may be as wide as the time between reads; but the reads fall at other
    phases of the period, and the windows of the last ``keep`` messages, shifted by their
    distance in periods, intersect to a narrow one. ``tolerance`` is the relative uncertainty
    of the period (the sender's crystal, its firmware loop): the shift of a message ``n``
    periods back is uncertain by ``n * period * tolerance``. Windows that do not intersect (a
    message lost, the stream restarted, a period that is not the one assumed) start the
    intersection again from the newest window alone (``resets``): a narrowed window is never
    narrower than all of the windows say.
    """

    def __init__(self, period: float, tolerance: float = 1e-3, keep: int = 32):
        if not period > 0:
            raise ValueError(f"period must be > 0, got {period}")
        self.period = period
        self.tolerance = tolerance
        self._seen: deque[tuple[int, float, float]] = deque(maxlen=keep)
        self._k = 0
        self.resets = 0

    def restart(self) -> None:
        """The stream starts again (its phase is new): forget the earlier windows."""
        self._seen.clear()

    def skip(self) -> None:
        """The next message came with no window to tell (it is counted, not used)."""
        self._k += 1

    def add(self, lo: float, hi: float) -> tuple[float, float]:
        """The next message arrived in ``[lo, hi]``; returns the window it was sent in."""
        self._k += 1
        k = self._k
        a, b = lo, hi
        for i, lo_i, hi_i in self._seen:
            shift = (k - i) * self.period
            slack = shift * self.tolerance
            a, b = max(a, lo_i + shift - slack), min(b, hi_i + shift + slack)
        if a > b:
            self.resets += 1
            self._seen.clear()
            a, b = lo, hi
        self._seen.append((k, lo, hi))
        return a, b


__all__ = ["DRIFT_BIN_S", "PeriodicArrivals", "SampleClock", "TimeMapping"]
