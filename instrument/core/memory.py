"""Giving freed memory back to the system between runs.

A run allocates and frees hundreds of MB (a 3000 s hold at 1 kHz kept for its fits, the fits'
arrays): glibc's allocator keeps most of what is freed in its heap for reuse, so a process
that runs protocol after protocol (a script, the GUI, a campaign worker) sits hundreds of MB
above what it holds, by an amount that wanders from run to run. Releasing the freed pages
once a run has ended keeps its memory flat (benchmarks/bench_run_memory.py).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc
from collections.abc import Callable


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim``, or None on another C library."""
    name = ctypes.util.find_library("c")
    try:
        trim = ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):
        return None
    if trim is not None:
        trim.argtypes = [ctypes.c_size_t]
        trim.restype = ctypes.c_int
    return trim


def release_freed_memory() -> None:
    """Collect unreachable cycles, then return the allocator's free pages to the system
    (glibc; elsewhere only the collection). Takes tens of milliseconds: call it between runs,
    never while one records."""
    gc.collect()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
