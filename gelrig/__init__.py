"""Composition roots of gelrig: the console entry point and the rig factory.

Nothing imports this package; it may import every other one.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("gelrig")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
