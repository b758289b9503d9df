"""Errors in the scientist's words (gui/messages.py): the next action for the user, the wire
detail for the log."""

import pytest

from gelrig.drivers.mcr501.codec import decode_reply, error_line
from gelrig.drivers.mcr501.commands import COMMANDS
from gelrig.gui.messages import REPLIES, explain, explain_fault, in_words
from gelrig.instrument.core.errors import (
    ConfigError,
    DeviceErrorReply,
    Disconnected,
    InstrumentTimeout,
    LimitError,
)
from gelrig.protocols.rig import NotHomed


def mcr_error(code: int) -> DeviceErrorReply:
    """The error the MCR 501 driver raises for an #ERR reply with ``code``."""
    try:
        decode_reply(COMMANDS["set_gap"], error_line(code))
    except DeviceErrorReply as exc:
        return exc
    raise AssertionError("no error raised")


@pytest.mark.parametrize("code", sorted(code for _name, code in REPLIES))
def test_each_rheometer_error_code_reads_as_its_next_action(code):
    exc = mcr_error(code)
    message = explain(exc)
    assert message.text == REPLIES[("MCR 501", code)]
    assert "MCR 501 error" not in message.text and type(exc).__name__ not in message.text
    assert message.detail == f"{type(exc).__name__}: {exc}"  # the wire, for the log


def test_the_gap_error_names_the_menu_path():
    assert "Manual -> Reference gap" in explain(mcr_error(12)).text


def test_a_code_of_another_instrument_is_not_read_as_the_rheometer_s():
    exc = DeviceErrorReply("KDC101 at sim://x refused MOT_MOVE_ABSOLUTE: busy (code 12)", 12)
    text = explain(exc).text
    assert "gap" not in text and "stage controller" in text


@pytest.mark.parametrize("exc, words", [
    (NotHomed("not homed"), "Manual -> Home"),
    (InstrumentTimeout("KDC101 at sim://x: no reply"), "did not answer"),
    (Disconnected("USB-6001 Dev1: gRPC server unreachable"), "force DAQ"),
    (ConnectionRefusedError(111, "Connection refused"), "address"),
])
def test_typed_errors_say_what_to_do(exc, words):
    message = explain(exc)
    assert words in message.text
    assert type(exc).__name__ in message.detail


def test_errors_written_for_people_keep_their_message():
    for exc in (LimitError("speed 5 mm/s beyond the stage's 2.3 mm/s; nothing moved"),
                ConfigError("max_force", 5.0, "allowed (0, 100] N", "rig.toml")):
        assert explain(exc).text == str(exc)


# ---- a run's Fault event carries the error's type name and message, not the error ----------

@pytest.mark.parametrize("code", sorted(code for _name, code in REPLIES))
def test_a_run_fault_of_each_rheometer_code_reads_as_the_manual_error_does(code):
    exc = mcr_error(code)  # its class may be a subclass (the trip codes, unknown command)
    message = explain_fault(type(exc).__name__, str(exc))
    assert message.text == explain(exc).text == REPLIES[("MCR 501", code)]
    assert message.detail == f"{type(exc).__name__}: {exc}"


@pytest.mark.parametrize("exc", [
    InstrumentTimeout("KDC101 at sim://x: no reply within 2 s"),
    Disconnected("USB-6001 Dev1: gRPC server unreachable"),
    DeviceErrorReply("KDC101 at sim://x refused MOT_MOVE_ABSOLUTE: busy (code 12)", 12),
    LimitError("speed 5 mm/s beyond the stage's 2.3 mm/s; nothing moved"),
])
def test_a_run_fault_reads_as_the_same_error_raised_by_hand(exc):
    kind = type(exc).__name__
    message = explain_fault(kind, str(exc))
    assert message.text == explain(exc).text
    assert message.detail == f"{kind}: {exc}"


def test_a_fault_kind_that_names_no_error_keeps_its_message():
    message = explain_fault("watchdog", "no samples for 5 s: the acquisition stalled")
    assert message.text == "no samples for 5 s: the acquisition stalled"
    assert message.detail.startswith("watchdog: ")


def test_a_run_s_end_reason_is_put_in_words_only_when_it_names_an_error():
    wire = "InstrumentTimeout: KDC101 at sim://x: no reply within 2 s"
    assert in_words(wire) == explain(InstrumentTimeout("KDC101 at sim://x: no reply within 2 s")
                                     ).text
    assert "InstrumentTimeout" not in in_words(wire)
    for reason in ("all steps completed", "aborted from the GUI", "step 2: value: 3"):
        assert in_words(reason) == reason
