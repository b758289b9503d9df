"""Errors in the scientist's words (gui/messages.py): the next action for the user, the wire
detail for the log."""

import pytest

from drivers.mcr501.codec import decode_reply, error_line
from drivers.mcr501.commands import COMMANDS
from gui.messages import REPLIES, explain
from instrument.errors import (
    ConfigError,
    DeviceErrorReply,
    Disconnected,
    InstrumentTimeout,
    LimitError,
)
from protocols.rig import NotHomed


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
