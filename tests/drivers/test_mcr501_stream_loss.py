"""The MCR 501 driver never drops stream points silently, and names a busy instrument.

Through pyvisa-py over TCP to the simulator (virtual time): the simulator keeps
``stream_buffer`` points and drops the oldest beyond it, setting the ``:STAT`` overflow flag.
"""

from __future__ import annotations

from typing import Any

import pytest

from gelrig.drivers.mcr501 import MCR501
from gelrig.drivers.mcr501.codec import InstrumentBusy, decode_reply
from gelrig.drivers.mcr501.commands import BUSY, COMMANDS, ERROR_CODES
from gelrig.drivers.mcr501.driver import StreamOverflow
from gelrig.instrument.core.errors import DeviceErrorReply
from gelrig.simulators.mcr501 import SimConfig
from tests.drivers.mcr501_harness import rig

BUFFER = 50
INTERVAL = 0.1


def test_points_dropped_between_reads_are_a_stream_overflow_naming_the_loss(rm: Any) -> None:
    with rig(rm, SimConfig(stream_buffer=BUFFER)) as r:
        r.drv.start_stream(INTERVAL)
        r.clock.sleep(2.0)
        assert len(r.drv.read_stream()) == 20  # read in time: no loss
        r.clock.sleep(8.0)  # 80 more points, 30 beyond the buffer
        with pytest.raises(StreamOverflow, match=r"about 30 points lost between t = 2\.000 s"):
            r.drv.read_stream()
        assert r.drv.status().overflow  # what the instrument says, too
        r.drv.stop_stream()  # the loss was reported once, not again


def test_points_read_in_time_raise_nothing(rm: Any) -> None:
    with rig(rm, SimConfig(stream_buffer=BUFFER)) as r:
        r.drv.start_stream(INTERVAL)
        got = 0
        for _ in range(5):
            r.clock.sleep(BUFFER * INTERVAL * 0.9)
            got += len(r.drv.read_stream())
        assert got == 5 * 45
        assert not r.drv.status().overflow
        r.drv.stop_stream()


def test_an_overflow_flag_at_the_stop_is_a_stream_overflow(rm: Any) -> None:
    with rig(rm, SimConfig(stream_buffer=BUFFER)) as r:
        r.drv.start_stream(INTERVAL)
        r.clock.sleep(10.0)  # 100 points, never read
        with pytest.raises(StreamOverflow, match="status flag"):
            r.drv.stop_stream()
        assert not r.drv.status().streaming  # the stop went out all the same


def test_busy_has_a_message_in_plain_words() -> None:
    assert BUSY == 20 and "another client" in ERROR_CODES[BUSY]
    with pytest.raises(InstrumentBusy, match=r"error 20.*another client") as info:
        decode_reply(COMMANDS["identify"], "#ERR[20;]")
    assert isinstance(info.value, DeviceErrorReply) and info.value.code == BUSY


def test_a_second_client_is_told_the_instrument_is_busy(rm: Any) -> None:
    with rig(rm) as r:
        second = MCR501(r.server.resource, r.clock, resource_manager=rm)
        with pytest.raises(InstrumentBusy, match="another client"):
            second.open()
        assert not second.is_open
        assert r.drv.status().mode == "idle"  # the first client is undisturbed
