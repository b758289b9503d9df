"""Peak decimation of a parametric curve (force against plate position) for drawing.

pyqtgraph's own downsampling and clip-to-view assume x increases along the curve; force
against position doubles back on itself (approach, hold, retract), so this keeps, for every
run of ``stride`` consecutive samples, the samples at the force minimum and maximum, in time
order. Work per update is proportional to the new samples; the stride grows by 4x (one full
pass) whenever the drawn curve would exceed ``cap`` points.
"""

from __future__ import annotations

import numpy as np

from gelrig.instrument.physics.contact import FloatArray


class PeakDecimator:
    """Incremental min/max decimation of (x, y) samples that only ever grow."""

    def __init__(self, cap: int = 20_000):
        self.cap = cap
        self.stride = 1
        self._done = 0  # raw samples already decimated (a multiple of stride)
        self._x: list[FloatArray] = []
        self._y: list[FloatArray] = []
        self._count = 0

    def reset(self) -> None:
        self.stride, self._done, self._x, self._y, self._count = 1, 0, [], [], 0

    def update(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Decimated curve of the first ``len(x)`` samples (x, y are the whole data so far)."""
        n = min(x.size, y.size)
        if n < self._done:  # the data was replaced, not grown
            self.reset()
        while (n // self.stride) * 2 > self.cap:
            self.stride *= 4
            self._done, self._x, self._y, self._count = 0, [], [], 0
        end = self._done + (n - self._done) // self.stride * self.stride
        if end > self._done:
            bx, by = self._peaks(x[self._done: end], y[self._done: end])
            self._x.append(bx)
            self._y.append(by)
            self._count += bx.size
            self._done = end
            if len(self._x) > 64:  # keep the list short: join the pieces
                self._x, self._y = [np.concatenate(self._x)], [np.concatenate(self._y)]
        out_x = np.concatenate([*self._x, x[end:n]])
        out_y = np.concatenate([*self._y, y[end:n]])
        return out_x, out_y

    def _peaks(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        if self.stride == 1:
            return x.copy(), y.copy()
        rows = x.size // self.stride
        xs = x.reshape(rows, self.stride)
        ys = y.reshape(rows, self.stride)
        lo = np.argmin(ys, axis=1)
        hi = np.argmax(ys, axis=1)
        first, second = np.minimum(lo, hi), np.maximum(lo, hi)
        r = np.arange(rows)
        out_x = np.empty(2 * rows)
        out_y = np.empty(2 * rows)
        out_x[0::2], out_x[1::2] = xs[r, first], xs[r, second]
        out_y[0::2], out_y[1::2] = ys[r, first], ys[r, second]
        return out_x, out_y
