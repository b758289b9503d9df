"""The MCR 501 command table: every command the shear rig sends, as data.

UNCONFIRMED. Anton Paar publishes no command reference for the MCR 501 and ships no driver
for it. This table follows the bracketed ASCII framing seen on the RS-232 line between the
vendor software and an MCR 501 (firmware 03.40: ``#VERS[?]``, ``#DATA[?]``, ``:STAT[?]``,
``:RUN[]``, records ``:MEAS[...]``), but the keywords, argument formats, units and replies
below are the project's reconstruction. Every entry must be confirmed on the instrument
before the rig runs on hardware (docs/decisions/0020). The simulator serves exactly this
table, so changing an entry here changes both sides at once. gelrig turns the arm only with
the time-limited ``:ROT[dir;rpm;duration]`` (docs/decisions/0201, UNVERIFIED like the rest);
the unbounded ``:ROT[dir;rpm]`` stays in the table for other clients of the simulator.

Framing: one line per message, ``KEY[field;field;...]`` terminated by CR LF. A query has the
single argument ``?``; an action without arguments has empty brackets. Actions answer
``KEY[OK]``; queries answer with their key and fields; any command may instead answer
``#ERR[code;text]``. ``#DATA[?]`` answers a header ``#DATA[count;remaining]`` followed by
``count`` record lines ``:MEAS[...]``. Wire units are the instrument's display units (mm, deg,
rpm, mN m, N, s); the driver converts to SI.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from types import MappingProxyType

#: Line termination for writes and reads (UNCONFIRMED).
TERMINATION = "\r\n"
#: Serial settings observed on the line: 38400 baud, 8 data bits, no parity, 1 stop bit,
#: XON/XOFF flow control.
BAUD_RATE = 38400
DATA_BITS = 8
#: The literal argument of a query, and the literal reply of an action.
QUERY = "?"
OK = "OK"
#: Most stream records one ``#DATA[?]`` answer carries.
MAX_RECORDS = 100

_FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_KEY = re.compile(r"^([#:][A-Z]{2,5})\[([^\[\]\r\n]*)\]$")


@dataclass(frozen=True)
class Field:
    """One ``;``-separated field: its name, how it is written, and what may appear."""

    name: str
    fmt: str
    pattern: str
    kind: str = "text"

    def encode(self, value: object) -> str:
        return format(value, self.fmt)

    def decode(self, raw: str) -> float | int | str:
        """The value of a raw field that matched :attr:`pattern`."""
        return self.converter(raw)

    @property
    def converter(self) -> Callable[[str], float | int | str]:
        """The function from a raw field that matched :attr:`pattern` to its value."""
        return _CONVERTERS.get(self.kind, str)


def _hex(raw: str) -> int:
    return int(raw, 16)


_CONVERTERS: dict[str, Callable[[str], float | int | str]] = {
    "number": float, "integer": int, "hex": _hex}


def number(name: str, fmt: str) -> Field:
    """A decimal number written with ``fmt`` (e.g. ``.4f``)."""
    return Field(name, fmt, _FLOAT, "number")


def integer(name: str) -> Field:
    """A non-negative decimal integer."""
    return Field(name, "d", r"\d+", "integer")


def hexword(name: str) -> Field:
    """A 4-digit upper-case hexadecimal word."""
    return Field(name, "04X", r"[0-9A-F]{4}", "hex")


def word(name: str, *choices: str) -> Field:
    """One of ``choices`` (upper-case)."""
    return Field(name, "s", "|".join(re.escape(c) for c in choices))


def text(name: str) -> Field:
    """Free text without brackets, ``;`` or line breaks."""
    return Field(name, "s", r"[^\[\];\r\n]*")


Shape = tuple[Field, ...] | str
"""Fields of a message, or a literal argument (``?``, ``OK`` or empty)."""


@dataclass(frozen=True)
class Message:
    """A message shape: key plus fields (or literal argument); compiles to a full-line regex.

    The hot paths (stream records at up to 100 a reply) use what is compiled once per shape:
    the regex, a ``str.format`` template with every field's format, and the field converters.
    """

    key: str
    shape: Shape

    @cached_property
    def regex(self) -> re.Pattern[str]:
        return _compile(self.key, self.shape)

    @cached_property
    def _names(self) -> frozenset[str]:
        return frozenset(f.name for f in self.shape) if not isinstance(self.shape, str) \
            else frozenset()

    @cached_property
    def _fields(self) -> tuple[Field, ...]:
        return () if isinstance(self.shape, str) else self.shape

    @cached_property
    def _template(self) -> str:
        """``KEY[{name:fmt};...]``: ``str.format`` calls ``format(value, fmt)`` per field."""
        body = ";".join(f"{{{f.name}:{f.fmt}}}" for f in self._fields)
        return f"{self.key}[{body}]"

    @cached_property
    def row_template(self) -> str:
        """``KEY[{0:fmt};{1:fmt};...]``: the line for field values in table order with
        ``str.format`` (the stream records' bulk path; :meth:`encode_row` checks the arity)."""
        body = ";".join(f"{{{i}:{f.fmt}}}" for i, f in enumerate(self._fields))
        return f"{self.key}[{body}]"

    @cached_property
    def _decoders(self) -> tuple[tuple[str, ...], tuple[Callable[[str], float | int | str], ...]]:
        return tuple(f.name for f in self._fields), tuple(f.converter for f in self._fields)

    def encode(self, **values: object) -> str:
        """The line for ``values`` (no termination)."""
        if isinstance(self.shape, str):
            if values:
                raise TypeError(f"{self.key} takes no values, got {sorted(values)}")
            return f"{self.key}[{self.shape}]"
        if values.keys() != self._names:
            missing = self._names - values.keys()
            extra = values.keys() - self._names
            raise TypeError(f"{self.key}: missing {sorted(missing)}, unexpected {sorted(extra)}")
        return self._template.format_map(values)

    def encode_row(self, *values: object) -> str:
        """The line for the field values in table order (the fast path for stream records)."""
        if len(values) != len(self._fields) or isinstance(self.shape, str):
            raise TypeError(f"{self.key} takes {len(self._fields)} values, got {len(values)}")
        return self.row_template.format(*values)

    def match(self, line: str) -> dict[str, str] | None:
        """The raw field strings of ``line`` if it has this shape, else None."""
        m = self.regex.match(line)
        return None if m is None else m.groupdict()

    def decode(self, line: str) -> dict[str, float | int | str] | None:
        """The typed field values of ``line`` if it has this shape, else None."""
        m = self.regex.match(line)
        if m is None:
            return None
        names, converters = self._decoders
        # Field patterns have no capturing groups of their own: groups() is in field order.
        return {n: c(raw) for n, c, raw in zip(names, converters, m.groups(), strict=True)}


_cache: dict[tuple[str, Shape], re.Pattern[str]] = {}


def _compile(key: str, shape: Shape) -> re.Pattern[str]:
    cached = _cache.get((key, shape))
    if cached is not None:
        return cached
    if isinstance(shape, str):
        body = re.escape(shape)
    else:
        body = ";".join(f"(?P<{f.name}>{f.pattern})" for f in shape)
    pattern = re.compile(f"^{re.escape(key)}\\[{body}\\]$")
    _cache[(key, shape)] = pattern
    return pattern


@dataclass(frozen=True)
class Command:
    """One table entry: the request the host sends and the reply it expects.

    ``records`` is set for commands whose reply header is followed by record lines.
    """

    name: str
    request: Message
    reply: Message
    doc: str
    records: Message | None = None


def split_key(line: str) -> tuple[str, str] | None:
    """``(key, body)`` of a framed line, or None if it is not ``KEY[body]``."""
    m = _KEY.match(line)
    return None if m is None else (m.group(1), m.group(2))


def _action(name: str, key: str, fields: Shape, doc: str) -> Command:
    return Command(name, Message(key, fields), Message(key, OK), doc)


def _query(name: str, key: str, fields: tuple[Field, ...], doc: str) -> Command:
    return Command(name, Message(key, QUERY), Message(key, fields), doc)


#: The measurement-stream record: instrument time since ``:RUN`` (s), angle (deg), torque
#: (mN m), normal force (N), gap (mm).
RECORD = Message(
    ":MEAS",
    (
        number("t_s", ".4f"),
        number("angle_deg", ".7f"),
        number("torque_mnm", ".6f"),
        number("force_n", ".6f"),
        number("gap_mm", ".4f"),
    ),
)

#: The error reply any command may get instead of its own.
ERROR = Message("#ERR", (integer("code"), text("text")))

_TABLE: tuple[Command, ...] = (
    _query(
        "identify",
        "#VERS",
        (text("model"), text("serial"), text("firmware")),
        "model, serial number, firmware version",
    ),
    _query(
        "status",
        ":STAT",
        (word("mode", "IDLE", "ROT", "HOLD"), hexword("flags")),
        "motor mode and state flags (see STATUS_FLAGS)",
    ),
    _action("zero_gap", ":GAPZ", "", "reference the gap; gap moves are refused before it"),
    _action("set_gap", ":GAP", (number("gap_mm", ".4f"),), "move the lift to a gap (mm)"),
    _query("read_gap", ":GAP", (number("gap_mm", ".4f"),), "current gap (mm)"),
    _action(
        "rotate",
        ":ROT",
        (word("direction", "CW", "CCW"), number("rpm", ".6e")),
        "turn at a constant speed (rpm >= 0) clockwise or counter-clockwise",
    ),
    _action(
        "rotate_for",
        ":ROT",
        (word("direction", "CW", "CCW"), number("rpm", ".6e"), number("duration_s", ".6g")),
        "turn at a constant speed for at most duration_s (0 < d <= 3600) from now, then ramp "
        "the speed to zero as :STOP does; the same direction and speed again before then "
        "renews the duration without touching the motion (the only rotation gelrig sends: "
        "docs/decisions/0201)",
    ),
    _action("stop", ":STOP", "", "ramp the speed to zero"),
    _action("hold", ":HOLD", "", "ramp to rest and hold the position"),
    _query("read_angle", ":ANG", (number("angle_deg", ".7f"),), "arm angle (deg)"),
    _query("read_torque", ":TORQ", (number("torque_mnm", ".6f"),), "motor torque (mN m)"),
    _query("read_normal_force", ":FN", (number("force_n", ".6f"),), "normal force (N)"),
    _action(
        "start_stream",
        ":RUN",
        (number("interval_s", ".6g"),),
        "record a point every interval (s) from now",
    ),
    _action("stop_stream", ":END", "", "stop recording; unread points are discarded"),
    Command(
        "read_stream",
        Message("#DATA", QUERY),
        Message("#DATA", (integer("count"), integer("remaining"))),
        f"up to {MAX_RECORDS} recorded points, then count :MEAS record lines",
        records=RECORD,
    ),
)

#: The command table, by name.
COMMANDS: MappingProxyType[str, Command] = MappingProxyType({c.name: c for c in _TABLE})

#: Bits of the ``:STAT`` flags word.
STATUS_FLAGS: MappingProxyType[str, int] = MappingProxyType(
    {
        "gap_moving": 0x01,
        "gap_referenced": 0x02,
        "streaming": 0x04,
        "accelerating": 0x08,
        "fault": 0x10,
        "overflow": 0x20,
    }
)

#: Error codes of ``#ERR`` replies (the project's convention; UNCONFIRMED).
ERROR_CODES: MappingProxyType[int, str] = MappingProxyType(
    {
        10: "unknown command",
        20: "instrument busy: another client (the vendor software or a second gelrig) holds "
            "its line; close that client and retry",
        11: "bad argument",
        12: "gap not referenced",
        13: "value out of range",
        31: "normal force overload (overlap limit)",
        32: "torque over range",
    }
)
#: The code of a request refused because another client holds the instrument.
BUSY = 20
#: Codes that mean the instrument stopped its motion by itself.
TRIP_CODES = frozenset({31, 32})
