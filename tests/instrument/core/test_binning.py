"""Equal-count bin means."""

import numpy as np
import pytest

from gelrig.instrument.core.binning import bin_means


def test_short_records_come_back_unchanged():
    t, y = np.arange(5.0), np.arange(5.0) ** 2
    tb, yb = bin_means(t, y, 5)
    assert tb is t and yb is y


def test_means_over_consecutive_runs():
    t = np.arange(10.0)
    tb, yb = bin_means(t, 2 * t, 3)  # runs [0, 3), [3, 6), [6, 10)
    assert tb == pytest.approx([1.0, 4.0, 7.5])
    assert yb == pytest.approx([2.0, 8.0, 15.0])
