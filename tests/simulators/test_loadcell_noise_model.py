"""The simulated load cell's noise beyond white (issue 30): a drift and an Ornstein-Uhlenbeck
part, exact at the sample times, continuous across blocks, on their own seeded stream."""

from __future__ import annotations

import numpy as np
import pytest

from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.simulators.usb6001.signals import LoadCellSignal

DT = 1e-3


def _signal(white: float = 0.0, drift: float = 0.0, correlated=(0.0, 1.0), seed: int = 5
            ) -> LoadCellSignal:
    contact = PlateSphereContact(Material(5000.0), 9.3e-3, 0.0, lambda t: -1e-3)  # no contact
    return LoadCellSignal(contact, LoadCellChain(), white, seed, drift, correlated)


def test_the_correlated_part_has_its_rms_and_correlation_time():
    v = _signal(correlated=(1e-3, 0.05)).volts(0.0, DT, 200_000)
    assert np.std(v) == pytest.approx(1e-3, rel=0.05)
    lag = round(0.05 / DT)
    rho = np.corrcoef(v[:-lag], v[lag:])[0, 1]
    assert rho == pytest.approx(np.exp(-1.0), abs=0.03)


def test_blocks_continue_one_record_and_the_white_stream_is_unchanged():
    whole = _signal(1e-3, 2e-3, (5e-4, 0.02)).volts(0.0, DT, 3000)
    split = _signal(1e-3, 2e-3, (5e-4, 0.02))
    parts = np.concatenate([split.volts(i * 1000 * DT, DT, 1000) for i in range(3)])
    assert parts == pytest.approx(whole, abs=1e-15)
    white = _signal(1e-3).volts(0.0, DT, 3000)
    rest = whole - white  # the drift and the correlated part, nothing of the white noise
    t = np.arange(3000) * DT
    slope = np.polyfit(t, rest, 1)[0]
    assert slope == pytest.approx(2e-3, abs=3e-4)  # 4.5 sigma of the OU part
    assert np.std(rest - slope * t) == pytest.approx(5e-4, rel=0.35)


def test_a_bad_correlated_part_is_refused():
    with pytest.raises(ValueError, match="correlated noise"):
        _signal(correlated=(1e-3, 0.0))


def test_the_correlated_part_goes_on_between_reads():
    """Reads a correlation time apart are as correlated as the process says, not as if the
    reads were contiguous."""
    tau = 0.05
    ends = []
    for seed in range(400):
        signal = _signal(correlated=(1e-3, tau), seed=seed)
        first = signal.volts(0.0, DT, 1)[0]
        ends.append((first, signal.volts(3 * tau, DT, 1)[0]))
    a, b = np.array(ends).T
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(np.exp(-3.0), abs=0.12)
