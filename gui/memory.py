"""Giving memory back after a run: the freed sample buffers of a finished run returned to the
operating system, so the GUI's footprint stays near its idle figure run after run.

numpy frees a run's buffers when the last reference goes, but glibc keeps freed blocks of the
rig thread's malloc arena mapped (the process grew by a run's worth each time, issue 15);
``malloc_trim(0)`` returns them. Elsewhere (no glibc) only the collector runs.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import sys
from collections.abc import Callable


def _trimmer() -> Callable[[int], int] | None:
    if not sys.platform.startswith("linux"):
        return None
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name or "libc.so.6")
        trim: Callable[[int], int] = libc.malloc_trim
    except (OSError, AttributeError):  # not glibc (musl has no malloc_trim)
        return None
    return trim


_TRIM = _trimmer()


def release() -> None:
    """Collect cycles, then hand freed heap memory back to the OS (where glibc allows)."""
    gc.collect()
    if _TRIM is not None:
        _TRIM(0)
