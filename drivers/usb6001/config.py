"""Configuration of the USB-6001 force input: which input, how it is wired, how it is read."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from instrument.errors import ConfigError
from instrument.units import to_si

TERMINALS = ("RSE", "DIFF")
OVER_RANGE_POLICIES = ("raise", "flag")
#: Lowest sample rate the driver accepts (Hz); the highest is the device's limit.
MIN_RATE = 100.0
RANGE_VOLTS = 10.0


@dataclass(frozen=True)
class Usb6001Config:
    """One AI input of a USB-6001 used as the force channel.

    ``buffer_seconds`` sizes the acquisition buffer (at least DAQmx's default is used);
    samples beyond ``over_range_volts`` in magnitude are over range, and ``on_over_range``
    says whether a read raises ForceOverRangeError (default) or only flags them;
    ``read_margin`` (s) is added to a block's duration to make its read timeout.
    """

    device: str = "Dev1"
    channel: str = "ai0"
    terminal: str = "RSE"
    buffer_seconds: float = 10.0
    over_range_volts: float = RANGE_VOLTS
    on_over_range: str = "raise"
    read_margin: float = 5.0

    def __post_init__(self) -> None:
        self._validate(None)

    @property
    def physical_channel(self) -> str:
        return f"{self.device}/{self.channel}"

    def _validate(self, source: str | None) -> None:
        if not self.device or "/" in self.device:
            raise ConfigError("device", self.device, "a DAQmx device name such as 'Dev1'", source)
        limit = 8 if self.terminal == "RSE" else 4
        allowed = [f"ai{i}" for i in range(limit)]
        if self.terminal not in TERMINALS:
            raise ConfigError("terminal", self.terminal, f"allowed: {', '.join(TERMINALS)}",
                              source)
        if self.channel not in allowed:
            raise ConfigError("channel", self.channel,
                              f"allowed with {self.terminal}: ai0..ai{limit - 1}", source)
        if not (math.isfinite(self.buffer_seconds) and 0.1 <= self.buffer_seconds <= 3600):
            raise ConfigError("buffer_seconds", self.buffer_seconds, "allowed [0.1, 3600] s",
                              source)
        if not 0 < self.over_range_volts <= 10.5:
            raise ConfigError("over_range_volts", self.over_range_volts, "allowed (0, 10.5] V",
                              source)
        if self.on_over_range not in OVER_RANGE_POLICIES:
            raise ConfigError("on_over_range", self.on_over_range,
                              f"allowed: {', '.join(OVER_RANGE_POLICIES)}", source)
        if not (math.isfinite(self.read_margin) and 0 <= self.read_margin <= 600):
            raise ConfigError("read_margin", self.read_margin, "allowed [0, 600] s", source)

    @classmethod
    def from_mapping(
        cls, mapping: Mapping[str, object], source: str | None = None
    ) -> Usb6001Config:
        """Build from a rig-file table; numbers may carry units ("10 s", "9.5 V")."""
        strings = {"device", "channel", "terminal", "on_over_range"}
        units = {"buffer_seconds": "s", "over_range_volts": "V", "read_margin": "s"}
        values: dict[str, object] = {}
        for key, raw in mapping.items():
            if key in strings:
                if not isinstance(raw, str):
                    raise ConfigError(key, raw, "expected a string", source)
                values[key] = raw.upper() if key == "terminal" else raw
            elif key in units:
                if not isinstance(raw, str | int | float):
                    raise ConfigError(key, raw, f"expected a number in {units[key]}", source)
                values[key] = to_si(raw, units[key], key, source)
            else:
                allowed = ", ".join(sorted(strings | set(units)))
                raise ConfigError(key, raw, f"unknown field; allowed: {allowed}", source)
        try:
            return cls(**values)  # type: ignore[arg-type]
        except ConfigError as exc:
            raise ConfigError(exc.field, exc.value, exc.allowed, source) from None
