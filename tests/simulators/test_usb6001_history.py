"""The DAQ twin's sample history keeps what concatenating each block and slicing kept."""

from __future__ import annotations

import numpy as np
import pytest

from gelrig.simulators.usb6001.device import SimTask, _keep_history


@pytest.mark.parametrize("keep", [1, 7, 100])
def test_history_equals_concatenate_then_slice(keep: int) -> None:
    rng = np.random.default_rng(keep)
    task = SimTask(name="t")
    task.hist = task.hist_buf = np.empty((2, 0))
    hist, hist_start, gen_pos = np.empty((2, 0)), 0, 0
    for _ in range(400):
        n = int(rng.integers(1, keep + 1))
        gap = int(rng.integers(0, 3)) if rng.random() < 0.1 else 0  # a skipped stretch
        first = gen_pos + gap
        block = rng.normal(size=(2, n))
        # The plain form this replaces.
        if first > gen_pos:
            hist, hist_start = block, first
        else:
            hist = np.concatenate([hist, block], axis=1)
        drop = hist.shape[1] - keep
        if drop > 0:
            hist, hist_start = hist[:, drop:], hist_start + drop
        _keep_history(task, block, first, keep)
        gen_pos = task.gen_pos = first + n
        assert task.hist_start == hist_start
        assert np.array_equal(task.hist, hist)
