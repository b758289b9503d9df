"""Where the hold of a ramp-and-hold record lies: the one hold detector of gelrig.

The plate ramps into the sphere, holds its position, then (in a recorded step) retracts.
With the overlap history the hold is every sample within a small tolerance of the deepest
overlap: the first such sample starts it, the last ends it, so the retract is not part of it.
Without the overlap the force shows where the ramp ends (it rises fast while loading and
relaxes slowly while held); the record is then taken to end with the hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.ndimage import uniform_filter1d

from gelrig.instrument.core.noise import robust_sigma

#: An overlap within this fraction of the deepest one (plus :data:`HELD_ABS`) is held.
HELD_REL = 1e-4
#: Absolute part of the held tolerance (m): a stage's position resolution is coarser.
HELD_ABS = 1e-9
#: Noise sigmas (of the smoothed force) below its peak at which the force-found hold starts.
FORCE_SIGMAS = 4.0


@dataclass(frozen=True)
class HoldSpan:
    """Samples ``[start, end)`` of the hold; ``top`` the held overlap (m, NaN from force)."""

    start: int
    end: int
    top: float

    @property
    def samples(self) -> int:
        """Number of samples in the hold."""
        return self.end - self.start


def find_hold(delta: ArrayLike | None = None, force: ArrayLike | None = None) -> HoldSpan:
    """The hold of a ramp-and-hold record, from the overlap ``delta`` (m) if given, else from
    the ``force`` (N). An empty or all-NaN overlap gives an empty span."""
    if delta is not None:
        d = np.asarray(delta, dtype=float)
        finite = np.isfinite(d)
        if not finite.any():
            return HoldSpan(0, 0, math.nan)
        top = float(np.max(d[finite]))
        held = np.flatnonzero(d >= top - (HELD_REL * abs(top) + HELD_ABS))
        return HoldSpan(int(held[0]), int(held[-1]) + 1, top)
    if force is None:
        raise ValueError("find_hold needs the overlap or the force")
    f = np.asarray(force, dtype=float)
    if f.size == 0:
        return HoldSpan(0, 0, math.nan)
    width = max(1, min(f.size // 1000, 51))
    smooth = uniform_filter1d(f, width, mode="nearest")
    # The first sample within the noise of the peak, not the noisy argmax on the flat top.
    sigma = robust_sigma(f)
    margin = FORCE_SIGMAS * (sigma if math.isfinite(sigma) else 0.0) / math.sqrt(width)
    return HoldSpan(int(np.argmax(smooth >= smooth.max() - margin)), f.size, math.nan)
