"""A first-order IIR filter, ``y = lfilter(b, a, x, zi=zi)``, without importing scipy.signal.

``scipy.signal`` costs a whole-package import (and, on its own, pulls in much of scipy) for
the one compiled routine gelrig uses: the direct-form-II-transposed filter behind
``scipy.signal.lfilter``. That routine lives in the extension ``scipy/signal/_sigtools``,
which depends on numpy only; it is loaded here from its file without running
``scipy/signal/__init__.py``. The result is the same call with the same arguments as
``lfilter`` makes (one-dimensional ``x``, ``a`` of length 2), so the output is identical to
the bit (tests/instrument/core/test_iir.py). Should scipy move or change that extension,
``scipy.signal.lfilter`` itself is used.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.instrument.core.arrays import FloatArray


@lru_cache(maxsize=1)
def _linear_filter() -> Callable[..., Any] | None:
    """scipy's compiled ``_linear_filter``, or None where it cannot be loaded on its own."""
    spec = importlib.util.find_spec("scipy")
    if spec is None or spec.origin is None:
        return None
    folder = Path(spec.origin).parent / "signal"
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = folder / f"_sigtools{suffix}"
        if path.is_file():
            break
    else:
        return None
    try:
        loader = importlib.machinery.ExtensionFileLoader("scipy.signal._sigtools", str(path))
        ext_spec = importlib.util.spec_from_file_location(
            "scipy.signal._sigtools", path, loader=loader)
        if ext_spec is None:
            return None
        module = importlib.util.module_from_spec(ext_spec)
        loader.exec_module(module)
        fn = module._linear_filter
    except Exception:
        return None
    return fn if callable(fn) else None


def first_order(b0: float, b1: float, a1: float, x: FloatArray, zi: float) -> FloatArray:
    """``lfilter((b0, b1), (1, a1), x, zi=(zi,))[0]`` for a 1-D float array ``x``."""
    fn = _linear_filter()
    if fn is None:
        from scipy.signal import lfilter

        out, _ = lfilter((b0, b1), (1.0, a1), x, zi=(zi,))
        return np.asarray(out, dtype=float)
    out, _ = fn(np.array((b0, b1)), np.array((1.0, a1)), np.asarray(x, dtype=float), -1,
                np.array((zi,)))
    return np.asarray(out, dtype=float)
