"""Encode requests and decode replies of the MCR 501 table, turning bad lines into typed errors.

Host side: :func:`encode` and :func:`decode_reply` / :func:`decode_record`. Instrument side
(the simulator): :func:`decode_request` and :func:`error_line`. A well-framed ``#ERR`` reply
raises :class:`DeviceErrorReply` (or :class:`InstrumentTrip` when the instrument stopped
itself); anything not matching the expected shape raises :class:`FramingError`.
"""

from __future__ import annotations

import re

from gelrig.drivers.mcr501.commands import (
    BUSY,
    COMMANDS,
    ERROR,
    ERROR_CODES,
    RECORD,
    TERMINATION,
    TRIP_CODES,
    Command,
    split_key,
)
from gelrig.instrument.core.errors import DeviceErrorReply, FramingError

Values = dict[str, float | int | str]


class InstrumentTrip(DeviceErrorReply):
    """The instrument stopped its motion by itself (torque over range, normal-force overload)."""


class UnknownCommand(DeviceErrorReply):
    """The instrument did not recognise a command of the table (confirm the table)."""


class InstrumentBusy(DeviceErrorReply):
    """Another client holds the instrument's line (error 20): nothing was done."""


def encode(name: str, **values: object) -> str:
    """The request line of table command ``name`` (no termination)."""
    try:
        command = COMMANDS[name]
    except KeyError:
        raise KeyError(f"{name!r} is not in the MCR 501 command table") from None
    return command.request.encode(**values)


#: Every ``#ERR`` reply starts so (ERROR's regex is anchored): other lines skip the regex.
_ERROR_PREFIX = f"{ERROR.key}["


def _raise_error(line: str, expected: str) -> None:
    if not line.startswith(_ERROR_PREFIX):
        return
    err = ERROR.decode(line)
    if err is None:
        return
    code = int(err["code"])
    detail = str(err["text"]) or ERROR_CODES.get(code, "unknown error")
    message = f"MCR 501 error {code} in reply to {expected}: {detail}"
    if code in TRIP_CODES:
        raise InstrumentTrip(message, code)
    if code == 10:
        raise UnknownCommand(message, code)
    if code == BUSY:
        raise InstrumentBusy(f"{message} ({ERROR_CODES[BUSY]})", code)
    raise DeviceErrorReply(message, code)


def decode_reply(command: Command, line: str) -> Values:
    """The typed fields of the reply ``line`` to ``command``.

    Raises DeviceErrorReply for ``#ERR`` and FramingError for anything else unexpected.
    """
    _raise_error(line, command.request.key)
    values = command.reply.decode(line)
    if values is None:
        expected = command.reply.regex.pattern
        raise FramingError(
            f"MCR 501: malformed reply to {command.name} ({command.request.key}): {line!r} "
            f"does not match {expected}"
        )
    return values


def decode_record(line: str) -> Values:
    """The typed fields of one ``:MEAS`` stream record."""
    _raise_error(line, RECORD.key)
    values = RECORD.decode(line)
    if values is None:
        raise FramingError(f"MCR 501: malformed stream record {line!r}")
    return values


#: A ``:MEAS`` record's values in table order: t (s), angle (deg), torque (mN m), force (N),
#: gap (mm).
RecordRow = tuple[float, float, float, float, float]
if isinstance(RECORD.shape, str) or any(f.kind != "number" for f in RECORD.shape):
    raise AssertionError("every :MEAS field must be a number")


def decode_record_row(line: str) -> RecordRow:
    """:func:`decode_record` as a tuple in table order (the driver's per-point fast path);
    the same validation and errors."""
    _raise_error(line, RECORD.key)
    m = RECORD.regex.match(line)
    if m is None:
        raise FramingError(f"MCR 501: malformed stream record {line!r}")
    t_s, angle_deg, torque_mnm, force_n, gap_mm = map(float, m.groups())
    return t_s, angle_deg, torque_mnm, force_n, gap_mm


#: Any number of ``:MEAS`` records, each followed by a newline: one match validates a batch
#: as the full-line regex validates each line (the field patterns have no groups).
_RECORD_BLOCK = re.compile(
    "(?:" + re.escape(RECORD.key) + r"\["
    + ";".join(f.pattern for f in RECORD.shape if not isinstance(RECORD.shape, str))
    + r"\]\n)*"
)
_RECORD_PREFIX = f"{RECORD.key}["


def decode_record_rows(lines: list[str]) -> list[float]:
    """The values of ``lines`` (``:MEAS`` records) in table order, flat (5 per record).

    The batch form of :func:`decode_record_row`, with the same validation and errors: a batch
    that does not match as a whole is decoded line by line to raise the first line's error.
    """
    if not lines:
        return []
    block = "\n".join(lines) + "\n"
    if _RECORD_BLOCK.fullmatch(block) is not None:
        values = block.replace(_RECORD_PREFIX, "").replace("]\n", ";").split(";")
        values.pop()  # after the last record's separator
        if len(values) == len(RECORD_FIELDS) * len(lines):
            return list(map(float, values))
    rows = [decode_record_row(line) for line in lines]  # raises for the first bad line
    raise FramingError(f"MCR 501: {len(lines)} stream records hold line breaks: {rows[:1]!r}")


#: The field names of a ``:MEAS`` record, in table order.
RECORD_FIELDS = tuple(f.name for f in RECORD.shape if not isinstance(RECORD.shape, str))

if isinstance(RECORD.shape, str) or any(not f.fmt.endswith("f") for f in RECORD.shape):
    raise AssertionError("every :MEAS field must be fixed-point for RECORD_MIN_LENGTH")
#: The fewest characters of a well-formed ``:MEAS`` line (termination excluded): every field
#: fixed-point, so none is shorter than zero written with its format. The transport may read
#: that many bytes per record still due without reading past a reply.
RECORD_MIN_LENGTH = len(RECORD.encode_row(*(0.0 for _ in RECORD_FIELDS)))
_HEAD = f"{RECORD.key}[".encode("ascii")
_WIDTHS = tuple(len(format(0.0, f.fmt)) for f in RECORD.shape)
_DECIMALS = tuple(int(f.fmt.strip(".f")) for f in RECORD.shape)
_TAIL = len("]") + len(TERMINATION)


def record_rest(prefix: bytes) -> int:
    """The fewest bytes (termination included) that can still complete a ``:MEAS`` line begun
    with ``prefix``: a fixed-point field has exactly its format's decimals after the point,
    and each field still to come at least its width at zero. 1 for what is not a prefix of a
    record (the line then fails to decode)."""
    if len(prefix) < len(_HEAD):
        return RECORD_MIN_LENGTH + len(TERMINATION) - len(prefix)
    if prefix.endswith(b"]"):
        return len(TERMINATION)
    if prefix.endswith(b"]\r"):
        return 1
    parts = prefix[len(_HEAD):].split(b";")
    j = len(parts) - 1
    if j >= len(_WIDTHS):
        return 1
    current = parts[j]
    point = current.find(b".")
    if point >= 0:
        here = max(0, _DECIMALS[j] - (len(current) - point - 1))
    else:
        digits = current.lstrip(b"+-")
        here = (0 if digits else 1) + 1 + _DECIMALS[j]
    later = sum(1 + w for w in _WIDTHS[j + 1:])
    return max(1, here + later + _TAIL)


_STREAM_HEADER = COMMANDS["read_stream"]


def decode_stream_header(line: str) -> tuple[int, int]:
    """(count, remaining) of a ``#DATA`` reply header: :func:`decode_reply` for
    ``read_stream`` without the dictionary (once per stream read)."""
    _raise_error(line, _STREAM_HEADER.request.key)
    m = _STREAM_HEADER.reply.regex.match(line)
    if m is None:
        decode_reply(_STREAM_HEADER, line)  # raises its FramingError
        raise AssertionError("unreachable")
    count, remaining = m.groups()
    return int(count), int(remaining)


class RequestError(Exception):
    """A request the instrument rejects; carries the ``#ERR`` code (simulator side)."""

    def __init__(self, code: int, text: str):
        self.code = code
        self.text = text
        super().__init__(f"{code}: {text}")


def decode_request(line: str) -> tuple[Command, Values]:
    """The table command and typed arguments of a request line (instrument side).

    Raises RequestError 10 for an unknown key and 11 for a known key with a bad argument.
    """
    literal = _LITERAL_REQUESTS.get(line)  # a query or argument-less action, as sent
    if literal is not None:
        return literal, {}
    return _decode_request(line)


def _decode_request(line: str) -> tuple[Command, Values]:
    parts = split_key(line)
    if parts is None:
        raise RequestError(10, "unknown command")
    key = parts[0]
    candidates = _BY_KEY.get(key)
    if candidates is None:
        raise RequestError(10, f"unknown command {key}")
    for command in candidates:
        values = command.request.decode(line)
        if values is not None:
            return command, values
    raise RequestError(11, f"bad argument for {key}")


def _by_key() -> dict[str, tuple[Command, ...]]:
    table: dict[str, list[Command]] = {}
    for command in COMMANDS.values():
        table.setdefault(command.request.key, []).append(command)
    return {key: tuple(commands) for key, commands in table.items()}


#: The table's commands by request key, in table order (``:GAP`` sets or reads the gap).
_BY_KEY = _by_key()

#: Requests without fields (``#DATA[?]``, ``:STOP[]``), line -> command: what
#: :func:`_decode_request` finds for them (the table's other shapes never match a literal).
_LITERAL_REQUESTS = {
    line: _decode_request(line)[0]
    for line in (c.request.encode() for c in COMMANDS.values()
                 if isinstance(c.request.shape, str))
}


#: Characters an ``#ERR`` text may not carry, and their stand-ins.
_TEXT_SAFE = str.maketrans(";[]\r\n", ",()  ")


def error_line(code: int, text: str = "") -> str:
    """An ``#ERR`` reply line; ``text`` defaults to the table's description of ``code``."""
    raw = text or ERROR_CODES.get(code, "error")
    clean = raw.translate(_TEXT_SAFE)
    return ERROR.encode(code=code, text=clean)
