"""Refuse a Qt binding that loses references to None and True.

PySide6 6.12.0 on Python 3.11 returns ``None`` from every void method and ``True`` from
``Signal.emit`` without taking a reference; on Python < 3.12, where these are not immortal,
the interpreter aborts after some thousands of calls (a GUI at the rig makes that many in a
minute), taking a running protocol down with it. PySide6 6.11 is sound. Probing costs a few
hundred calls; see docs/decisions/0040-gui-threading.md.
"""

from __future__ import annotations

import ctypes
import sys

import PySide6
from PySide6.QtCore import QObject, Signal

from gelrig.instrument.core.errors import GelrigError

_CALLS = 200


class _Probe(QObject):
    ping = Signal()


def binding_problem() -> str:
    """Why this Qt binding cannot run the GUI safely ('' if it can)."""
    probe = _Probe()
    none_before, true_before = sys.getrefcount(None), sys.getrefcount(True)
    for _ in range(_CALLS):
        probe.setObjectName("probe")  # a void method: returns None
        probe.ping.emit()  # returns True
    lost = {"None": none_before - sys.getrefcount(None),
            "True": true_before - sys.getrefcount(True)}
    for name, n in lost.items():  # give back what the probe took
        for _ in range(max(n, 0)):
            ctypes.pythonapi.Py_IncRef(ctypes.py_object(None if name == "None" else True))
    leaking = [name for name, n in lost.items() if n >= _CALLS * 3 // 4]
    if not leaking:
        return ""
    return (f"PySide6 {PySide6.__version__} on Python {sys.version.split()[0]} loses a reference "
            f"to {' and '.join(leaking)} on every call and would crash the application; "
            "install another PySide6, e.g. pip install 'PySide6-Essentials>=6.6,<6.12'")


def check_binding() -> None:
    """Raise GelrigError if the binding is unsound."""
    problem = binding_problem()
    if problem:
        raise GelrigError(problem)
