"""The hold detector on ramp-hold-retract records with known hold samples."""

import math

import numpy as np
import pytest

from gelrig.instrument.analysis.hold import find_hold

DT = 0.1
T = np.arange(0, 100, DT)  # ramp 0-30 s, hold 30-80 s, retract 80-100 s
TOP = 3e-4


def overlap(t):
    return np.where(t < 80, np.minimum(t * 1e-5, TOP), TOP - (t - 80) * 1e-5)


def test_overlap_gives_start_end_and_depth():
    span = find_hold(delta=overlap(T))
    assert T[span.start] == pytest.approx(30.0, abs=DT)
    assert T[span.end - 1] == pytest.approx(80.0, abs=DT)  # the retract is not held
    assert span.samples == span.end - span.start
    assert span.top == pytest.approx(TOP)


def test_nan_overlap_samples_are_skipped():
    d = overlap(T)
    d[::7] = np.nan
    d[-1] = np.nan
    span = find_hold(delta=d)
    assert T[span.start] == pytest.approx(30.0, abs=2 * DT)
    assert span.top == pytest.approx(TOP)


def test_no_overlap_data_is_an_empty_span():
    assert find_hold(delta=np.full(10, np.nan)).samples == 0
    assert find_hold(delta=[]).samples == 0
    assert math.isnan(find_hold(delta=[]).top)


def test_force_alone_finds_the_end_of_the_ramp():
    t = np.arange(0, 600, 0.01)  # ramp to 1 N over 30 s, then a slow relaxation
    rise = np.minimum(t / 30.0, 1.0)
    force = rise * (0.8 + 0.2 * np.exp(-np.maximum(t - 30.0, 0.0) / 500.0))
    force += np.random.default_rng(2).normal(0.0, 1e-3, t.size)
    span = find_hold(force=force)
    assert t[span.start] == pytest.approx(30.0, abs=0.5)
    assert span.end == t.size and math.isnan(span.top)


def test_needs_overlap_or_force():
    with pytest.raises(ValueError, match="overlap or the force"):
        find_hold()
