"""Shared test setup: Qt offscreen for every test that touches the GUI, and the fast tier.

The fast tier (`make test-fast`, `pytest -m "not slow"`) leaves out the tests marked slow by
hand and those listed in ``tests/slow_tests.txt``: node ids of tests (or whole modules) that
took longer than the threshold in a full run (regenerate with ``python tests/slow_tests.py
REPORT``, then ``--merge`` on a report of the fast tier).
"""

import os
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

_SLOW_LIST = Path(__file__).with_name("slow_tests.txt")


def _listed_slow() -> frozenset[str]:
    if not _SLOW_LIST.exists():
        return frozenset()
    lines = (line.strip() for line in _SLOW_LIST.read_text(encoding="utf-8").splitlines())
    return frozenset(line for line in lines if line and not line.startswith("#"))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    slow = _listed_slow()
    for item in items:
        if (item.nodeid in slow or item.nodeid.split("[")[0] in slow
                or item.nodeid.split("::")[0] in slow):  # a whole module
            item.add_marker(pytest.mark.slow)
