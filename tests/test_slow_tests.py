"""The fast tier's list is made from a durations log: slow phases listed once, by test."""

from tests.slow_tests import slow_ids

_LOG = """\
============================= slowest durations ==============================
12.50s call     tests/gelrig/test_cli_run.py::test_paper_run[virtual]
4.10s call     tests/gelrig/test_cli_run.py::test_paper_run[paced]
3.20s setup    tests/gui/test_app.py::test_window
0.50s call     tests/instrument/core/test_clock.py::test_quick
(2 durations < 0.005s hidden.)
"""


def test_phases_over_the_threshold_are_listed_once_without_parameters():
    assert slow_ids(_LOG, over=3.0) == ["tests/gelrig/test_cli_run.py::test_paper_run",
                                        "tests/gui/test_app.py::test_window"]


def test_a_higher_threshold_lists_fewer():
    assert slow_ids(_LOG, over=5.0) == ["tests/gelrig/test_cli_run.py::test_paper_run"]
