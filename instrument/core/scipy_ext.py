"""scipy's compiled routines without the packages around them (start-up, issue 31 item 3).

``import scipy.signal`` or ``scipy.stats`` runs the whole package (0.1-0.5 s, much of scipy)
for the one compiled function gelrig needs from it. The extension modules holding those
functions depend on numpy only, so they are loaded here from their files without running the
package's ``__init__``; the functions are then called exactly as scipy's wrappers call them
(identical results: tests/instrument/core/test_scipy_ext.py). Where an extension cannot be
found or loaded (scipy moved it), callers use scipy's public function instead.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
from functools import cache
from pathlib import Path
from types import ModuleType

import numpy as np

from gelrig.instrument.core.arrays import FloatArray


@cache
def extension(package: str, name: str) -> ModuleType | None:
    """The extension module ``scipy.<package>.<name>``, loaded on its own; None if missing."""
    full = f"scipy.{package}.{name}"
    if full in sys.modules:
        return sys.modules[full]
    spec = importlib.util.find_spec("scipy")
    if spec is None or spec.origin is None:
        return None
    folder = Path(spec.origin).parent / package
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = folder / f"{name}{suffix}"
        if path.is_file():
            break
    else:
        return None
    try:
        loader = importlib.machinery.ExtensionFileLoader(full, str(path))
        ext_spec = importlib.util.spec_from_file_location(full, path, loader=loader)
        if ext_spec is None:
            return None
        module = importlib.util.module_from_spec(ext_spec)
        loader.exec_module(module)
    except Exception:
        return None
    return module


def first_order(b0: float, b1: float, a1: float, x: FloatArray, zi: float) -> FloatArray:
    """``lfilter((b0, b1), (1, a1), x, zi=(zi,))[0]`` for a 1-D float array ``x``: the call
    ``scipy.signal.lfilter`` makes to ``_sigtools._linear_filter`` for a two-term ``a``."""
    ext = extension("signal", "_sigtools")
    if ext is None:
        from scipy.signal import lfilter

        out, _ = lfilter((b0, b1), (1.0, a1), x, zi=(zi,))
        return np.asarray(out, dtype=float)
    out, _ = ext._linear_filter(np.array((b0, b1)), np.array((1.0, a1)),
                                np.asarray(x, dtype=float), -1, np.array((zi,)))
    return np.asarray(out, dtype=float)


def siegel_slope(y: FloatArray, x: FloatArray) -> float:
    """``scipy.stats.siegelslopes(y, x).slope`` (repeated medians, hierarchical) for float
    arrays of the same length >= 2: the call scipy's wrapper makes to its pythran routine."""
    ext = extension("stats", "_stats_pythran")
    if ext is None:
        from scipy.stats import siegelslopes

        return float(siegelslopes(y, x).slope)
    yy = np.asarray(y).ravel()
    xx = np.asarray(x, dtype=float).ravel()
    if len(xx) != len(yy) or len(xx) < 2:
        raise ValueError(f"siegel_slope needs x and y of one length >= 2, got {len(xx)}, "
                         f"{len(yy)}")
    dtype = np.result_type(xx, yy, np.float32)
    slope, _ = ext.siegelslopes(yy.astype(dtype), xx.astype(dtype), "hierarchical")
    return float(np.asarray(slope)[()])
