"""The typed errors every layer raises, so callers can tell a user exactly what went wrong."""

from __future__ import annotations

import json


class GelrigError(Exception):
    """Base of every error gelrig raises on purpose."""


class ConfigError(GelrigError, ValueError):
    """A rig file, protocol file, CLI option or data file holds a value that is not allowed.

    The message names the source (file or option), the field, the value and what is allowed.
    """

    def __init__(self, field: str, value: object, allowed: str, source: str | None = None):
        self.field = field
        self.value = value
        self.allowed = allowed
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{field} = {shown(value)}: {allowed}")


class Refused(ConfigError):
    """A protocol, or a script's step, that the rig's caps or the run's bounds refuse before
    anything of the run moved: nothing was recorded (no run folder is left)."""

    def __init__(self, line: str, source: str | None = None):
        Exception.__init__(self, line)
        self.field, self.value, self.allowed, self.source = "protocol", source, line, source


def shown(value: object) -> str:
    """A value as a TOML file would hold it: strings in double quotes, floats short."""
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, float):
        text = repr(value)
        return text if len(text) <= 12 else f"{value:.6g}"
    if isinstance(value, bool):
        return "true" if value else "false"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


class InstrumentError(GelrigError):
    """Something went wrong talking to an instrument."""


class InstrumentTimeout(InstrumentError):
    """The instrument did not answer in time."""


class FramingError(InstrumentError):
    """Bytes on the wire that do not form a valid message of the instrument's protocol."""


class DeviceErrorReply(InstrumentError):
    """The instrument answered with an error reply."""

    def __init__(self, message: str, code: int | None = None):
        self.code = code
        super().__init__(message)


class Disconnected(InstrumentError):
    """The transport to the instrument closed or vanished."""


class NotSent(Disconnected):
    """A request never left: writing it to the link failed (the link is down).

    The safe stop tells a stop that went out (and may not have been answered) from one that
    never did by this type.
    """


class LimitError(GelrigError):
    """A requested move or setting lies outside the configured safety limits; nothing moved."""


class InterlockTripped(GelrigError):
    """An interlock (force, torque, travel, overlap) tripped; motion was stopped."""
