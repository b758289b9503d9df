"""scipy's compiled routines without their packages equal scipy's public functions to the bit."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.stats import siegelslopes

from gelrig.instrument.core import scipy_ext


@pytest.mark.parametrize("n", [0, 1, 2, 1000, 200_001])
def test_first_order_equals_lfilter_to_the_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-9, 9, n)
    for e in (0.0, 1e-12, 0.5, 0.999999, 1.0):
        w, zi = 0.37, rng.standard_normal()
        want, _ = lfilter([w, -w], [1.0, -e], x, zi=[zi])
        assert np.array_equal(scipy_ext.first_order(w, -w, -e, x, zi), want)
        # a one-coefficient numerator (the load-cell chain's low-pass) as b1 = 0
        want1, _ = lfilter([1.0 - e], [1.0, -e], x, zi=[zi])
        assert np.array_equal(scipy_ext.first_order(1.0 - e, 0.0, -e, x, zi), want1)


def test_the_fallback_is_scipy_signal(monkeypatch: pytest.MonkeyPatch) -> None:
    x = np.linspace(0.0, 1.0, 50)
    fast = scipy_ext.first_order(0.2, -0.1, -0.9, x, 0.3)
    monkeypatch.setattr(scipy_ext, "extension", lambda package, name: None)
    assert np.array_equal(scipy_ext.first_order(0.2, -0.1, -0.9, x, 0.3), fast)


def test_it_imports_neither_scipy_signal_nor_scipy_stats() -> None:
    code = ("import sys, numpy as np\n"
            "from gelrig.instrument.core.scipy_ext import first_order, siegel_slope\n"
            "first_order(0.5, -0.5, -0.9, np.ones(10), 0.0)\n"
            "siegel_slope(np.ones(5), np.arange(5.0))\n"
            "print(sorted(m for m in sys.modules\n"
            "             if m.startswith(('scipy.signal', 'scipy.stats'))))\n"
            "from scipy.signal import lfilter\n"  # the package still imports afterwards
            "print(lfilter([1.0], [1.0, -0.5], np.ones(3)).tolist())\n"
            "from scipy.stats import siegelslopes\n"
            "print(float(siegelslopes([0.0, 2.0, 4.0]).slope))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    # only the extension itself is loaded, not the package around it
    assert out.stdout.splitlines() == ["['scipy.signal._sigtools', 'scipy.stats._stats_pythran']",
                                       "[1.0, 1.5, 1.75]", "2.0"]


@pytest.mark.parametrize("n", [2, 3, 40, 257])
def test_siegel_slope_equals_scipy_stats_to_the_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    x = np.sort(rng.integers(0, 10 * n, n)).astype(float)
    y = 1e-6 * x + rng.standard_normal(n) * 1e-4
    y[rng.random(n) < 0.2] += 0.01  # late arrivals
    assert scipy_ext.siegel_slope(y, x) == float(siegelslopes(y, x).slope)
    ints = rng.integers(-5, 5, n)  # an integer y, as scipy casts it
    assert scipy_ext.siegel_slope(ints, x) == float(siegelslopes(ints, x).slope)
    with pytest.raises(ValueError, match="length"):
        scipy_ext.siegel_slope(y[:1], x[:1])


def test_the_siegel_fallback_is_scipy_stats(monkeypatch: pytest.MonkeyPatch) -> None:
    x, y = np.arange(30.0), np.sin(np.arange(30.0))
    fast = scipy_ext.siegel_slope(y, x)
    monkeypatch.setattr(scipy_ext, "extension", lambda package, name: None)
    assert scipy_ext.siegel_slope(y, x) == fast
