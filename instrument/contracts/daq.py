"""The ``[force]`` table of a compression rig: which USB-6001 input reads the load cell, how.

Configuration only (no nidaqmx here), so the rig file can be validated and shown without the
driver; the USB-6001 driver (drivers/usb6001) consumes it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from gelrig.instrument.core.fields import Choice, Config, Field, Text, Where, param

TERMINALS = ("RSE", "DIFF")
OVER_RANGE_POLICIES = ("raise", "flag")
#: Lowest sample rate the driver accepts (Hz); the highest is the device's limit.
MIN_RATE = 100.0
#: The USB-6001's only analog input range (+-V).
RANGE_VOLTS = 10.0


@dataclass(frozen=True)
class Usb6001Config(Config):
    """One AI input of a USB-6001 used as the force channel.

    ``buffer_seconds`` sizes the acquisition buffer (at least DAQmx's default is used);
    samples beyond ``over_range_volts`` in magnitude are over range, and ``on_over_range``
    says whether a read raises ForceOverRangeError (default) or only flags them;
    ``read_margin`` (s) is added to a block's duration to make its read timeout;
    ``call_timeout`` (s) is the deadline of every call to an NI gRPC Device Server, added to
    a read's own timeout for that read (ADR 0060).
    """

    section: ClassVar[str] = "force"

    device: str = param(Text("device", "Dev1", "a DAQmx device name such as 'Dev1'",
                             lambda s: bool(s) and "/" not in s))
    channel: str = param(Text("channel", "ai0", "ai0..ai7 (RSE) or ai0..ai3 (DIFF)",
                              lambda s: s in {f"ai{i}" for i in range(8)}))
    terminal: str = param(Choice("terminal", TERMINALS, "RSE", normalize=str.upper))
    buffer_seconds: float = param(Field("buffer_seconds", "s", 10.0, 0.1, 3600.0,
                                        help="host buffer of the acquisition"))
    over_range_volts: float = param(Field("over_range_volts", "V", RANGE_VOLTS, 0.0, 10.5,
                                          lo_open=True))
    on_over_range: str = param(Choice("on_over_range", OVER_RANGE_POLICIES, "raise"))
    read_margin: float = param(Field("read_margin", "s", 5.0, 0.0, 600.0,
                                     help="added to a block's duration for its read deadline"))
    call_timeout: float = param(Field("call_timeout", "s", 2.0, 0.0, 600.0, lo_open=True,
                                      help="deadline of every gRPC call (reads: plus their "
                                      "own timeout)"))

    def validate(self, where: Where) -> None:
        limit = 8 if self.terminal == "RSE" else 4
        if self.channel not in {f"ai{i}" for i in range(limit)}:
            raise where.error("channel", self.channel,
                              f"allowed with {self.terminal}: ai0..ai{limit - 1}")

    @property
    def physical_channel(self) -> str:
        return f"{self.device}/{self.channel}"
