"""The first-order filter without scipy.signal equals scipy.signal.lfilter to the bit."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.signal import lfilter

from gelrig.instrument.core import iir


@pytest.mark.parametrize("n", [0, 1, 2, 1000, 200_001])
def test_first_order_equals_lfilter_to_the_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-9, 9, n)
    for e in (0.0, 1e-12, 0.5, 0.999999, 1.0):
        w, zi = 0.37, rng.standard_normal()
        want, _ = lfilter([w, -w], [1.0, -e], x, zi=[zi])
        assert np.array_equal(iir.first_order(w, -w, -e, x, zi), want)
        # a one-coefficient numerator (the load-cell chain's low-pass) as b1 = 0
        want1, _ = lfilter([1.0 - e], [1.0, -e], x, zi=[zi])
        assert np.array_equal(iir.first_order(1.0 - e, 0.0, -e, x, zi), want1)


def test_the_fallback_is_scipy_signal(monkeypatch: pytest.MonkeyPatch) -> None:
    x = np.linspace(0.0, 1.0, 50)
    fast = iir.first_order(0.2, -0.1, -0.9, x, 0.3)
    monkeypatch.setattr(iir, "_linear_filter", lambda: None)
    assert np.array_equal(iir.first_order(0.2, -0.1, -0.9, x, 0.3), fast)


def test_it_does_not_import_scipy_signal() -> None:
    code = ("import sys, numpy as np\n"
            "from gelrig.instrument.core.iir import first_order, _linear_filter\n"
            "assert _linear_filter() is not None\n"
            "first_order(0.5, -0.5, -0.9, np.ones(10), 0.0)\n"
            "print(sorted(m for m in sys.modules if m.startswith('scipy.signal')))\n"
            "from scipy.signal import lfilter\n"  # the package still imports afterwards
            "print(lfilter([1.0], [1.0, -0.5], np.ones(3)).tolist())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    # only the extension itself is loaded, not the package around it
    assert out.stdout.splitlines() == ["['scipy.signal._sigtools']", "[1.0, 1.5, 1.75]"]
