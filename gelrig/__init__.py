"""Composition roots of gelrig: the console entry point and the rig factory.

Nothing imports this package; it may import every other one.
"""

from __future__ import annotations


def __getattr__(name: str) -> str:
    """``__version__``, looked up on first use (importlib.metadata is slow to import)."""
    if name != "__version__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("gelrig")
    except PackageNotFoundError:  # running from a source tree that is not installed
        found = "0+unknown"
    globals()["__version__"] = found
    return found
