"""The one stop-on-fault path of every driver: stop first, never hide the original error."""

from __future__ import annotations

import logging
from contextlib import AbstractContextManager

import pytest

from gelrig.instrument.contracts.stop_first import guarded, stop_on_fault
from gelrig.instrument.core.errors import Disconnected, InstrumentTimeout


class Events(list[str]):
    def stop(self) -> None:
        self.append("stop")


@pytest.mark.parametrize("exc", [KeyboardInterrupt(), InstrumentTimeout("late"),
                                 RuntimeError("bug"), SystemExit(1)])
def test_any_exception_stops_first_then_propagates_unchanged(exc: BaseException) -> None:
    events = Events()
    with pytest.raises(type(exc)) as info, stop_on_fault(events.stop):
        events.append("call")
        raise exc
    assert info.value is exc
    assert events == ["call", "stop"]


def test_no_stop_without_a_fault_or_when_nothing_moves() -> None:
    events = Events()
    with stop_on_fault(events.stop):
        events.append("call")
    with pytest.raises(KeyboardInterrupt), stop_on_fault(events.stop, needed=lambda: False):
        raise KeyboardInterrupt
    assert events == ["call"]


def test_spared_exceptions_propagate_without_a_stop() -> None:
    events = Events()
    with pytest.raises(InstrumentTimeout), stop_on_fault(events.stop, spare=(Disconnected,
                                                                             InstrumentTimeout)):
        raise InstrumentTimeout("a report, not a fault")
    with pytest.raises(KeyboardInterrupt), stop_on_fault(events.stop, spare=(Disconnected,)):
        raise KeyboardInterrupt
    assert events == ["stop"]


@pytest.mark.parametrize("failure", [Disconnected("cable pulled"), KeyboardInterrupt()])
def test_a_failing_stop_is_logged_and_the_original_error_raised(
    caplog: pytest.LogCaptureFixture, failure: BaseException
) -> None:
    def stop() -> None:
        raise failure

    original = InstrumentTimeout("no reply")
    with caplog.at_level(logging.ERROR, "gelrig.instrument.contracts.stop_first"), \
            pytest.raises(InstrumentTimeout) as info, stop_on_fault(stop, what="stage"):
        raise original
    assert info.value is original
    (record,) = caplog.records
    assert record.levelno == logging.ERROR
    assert "stage: the stop after InstrumentTimeout failed" in record.getMessage()
    assert record.exc_info is not None and record.exc_info[1] is failure
    assert info.value.__notes__ == [
        f"stage: the stop after this error failed: {type(failure).__name__}: {failure}"]


def test_nested_guards_stop_once_per_fault() -> None:
    events = Events()
    with pytest.raises(KeyboardInterrupt), stop_on_fault(events.stop), \
            stop_on_fault(events.stop):
        raise KeyboardInterrupt
    assert events == ["stop"]
    other = Events()
    with pytest.raises(KeyboardInterrupt), stop_on_fault(events.stop), \
            stop_on_fault(other.stop):
        raise KeyboardInterrupt
    assert events == ["stop", "stop"] and other == ["stop"]  # two instruments: both stop


class Axis:
    def __init__(self) -> None:
        self.moving = False
        self.stops = 0

    def _guard(self) -> AbstractContextManager[None]:
        return stop_on_fault(self._stop, needed=lambda: self.moving)

    def _stop(self) -> None:
        self.stops += 1
        self.moving = False

    @guarded
    def move(self, interrupt: bool) -> str:
        self.moving = True
        if interrupt:
            raise KeyboardInterrupt
        return "moving"


def test_guarded_methods_run_inside_the_guard() -> None:
    axis = Axis()
    assert axis.move(False) == "moving" and axis.stops == 0
    with pytest.raises(KeyboardInterrupt):
        axis.move(True)
    assert axis.stops == 1 and not axis.moving
    assert Axis.move.__name__ == "move"
