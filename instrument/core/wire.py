"""Wire log and replay (issue 30): every exchange with an instrument, recorded with its host
time, and served back to the same driver later.

A driver opens its link through :func:`serial_port` (KDC101 bytes), :func:`grpc_channel`
(USB-6001 RPCs) or :func:`line_transport` (MCR 501 lines). Normally these return the link
itself. While :func:`recording` is active they wrap it so that each call (a write, a read and
what it returned, ``in_waiting``, a purge; an RPC's method, request and response or error; a
line and a failure) is appended to a :class:`WireLog` with the driver's clock time before and
after the call. While :func:`replaying` is active they return a stand-in that checks each call
against the next recorded one of that instrument, answers what the instrument answered, and
moves a virtual clock to the recorded time (so the driver sees the
same timing); the first call that differs raises :class:`ReplayDiverged` naming the
instrument, the call's index, its recorded host time and both sides.

The log is JSON lines (``wire.jsonl``): a header (the command line), then one object per call
with short keys: ``i`` instrument, ``k`` kind, ``s`` / ``t`` host time at its start / end (s,
exact floats), ``b`` bytes (hex), ``n`` a count, ``m`` an RPC method, ``q`` / ``r`` request /
response (hex), ``e`` an error. It is
bounded: past ``max_bytes`` one ``{"k": "full"}`` record ends it, and a replay reaching that
point says so. A real instrument's log replayed through the driver is a regression test.
"""

from __future__ import annotations

import contextlib
import json
import threading
from collections import deque
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from gelrig.instrument.core.clock import Clock, VirtualClock
from gelrig.instrument.core.errors import GelrigError

T = TypeVar("T")

#: Default bound of a wire log (bytes on disk).
MAX_BYTES = 256 * 1024 * 1024


class ReplayDiverged(GelrigError):
    """The driver asked something the recording did not: where, and what differs."""


class WireLog:
    """An append-only, size-bounded JSON-lines log of instrument exchanges."""

    def __init__(self, path: str | Path, header: dict[str, Any] | None = None,
                 max_bytes: int = MAX_BYTES):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.max_bytes = max_bytes
        self._file = self.path.open("w", encoding="utf-8")
        self._lock = threading.Lock()
        self.size = 0
        self.records = 0
        self.full = False
        self._write({"k": "head", **(header or {})})

    def _write(self, record: dict[str, Any]) -> None:
        line = json.dumps(record, separators=(",", ":")) + "\n"
        self._file.write(line)
        self.size += len(line)

    def add(self, instrument: str, kind: str, start: float, t: float, **fields: Any) -> None:
        """One call of ``instrument``: its kind, the clock when it began and ended (s)."""
        with self._lock:
            if self.full or self._file.closed:
                return
            record = {"i": instrument, "k": kind, "s": start, "t": t,
                      **fields}
            if self.size + len(json.dumps(record)) + 64 > self.max_bytes:
                self.full = True
                self._write({"k": "full", "records": self.records})
                return
            self._write(record)
            self.records += 1

    def close(self) -> None:
        with self._lock:
            if not self._file.closed:
                self._file.close()


class Replay:
    """A recorded wire log, served back call by call per instrument."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.header: dict[str, Any] = {}
        self._queues: dict[str, deque[dict[str, Any]]] = {}
        self._served: dict[str, int] = {}
        self.truncated = False
        self._offset: float | None = None
        with self.path.open(encoding="utf-8") as f:
            for number, line in enumerate(f, 1):
                try:
                    record = json.loads(line)
                except json.JSONDecodeError:
                    raise ReplayDiverged(f"{self.path}: line {number} is not a wire-log "
                                         "record") from None
                if record.get("k") == "head":
                    self.header = record
                elif record.get("k") == "full":
                    self.truncated = True
                else:
                    self._queues.setdefault(record["i"], deque()).append(record)
        self.recorded = {name: len(q) for name, q in self._queues.items()}

    def left(self) -> dict[str, int]:
        """Recorded calls not yet served, per instrument."""
        return {name: len(q) for name, q in self._queues.items() if q}

    def served(self) -> dict[str, int]:
        return dict(self._served)

    def next(self, instrument: str, kind: str, what: str, clock: Clock) -> dict[str, Any]:
        """The next recorded call of ``instrument``, which must be a ``kind``; the clock is
        moved to its time (a virtual clock only)."""
        queue = self._queues.get(instrument)
        index = self._served.get(instrument, 0)
        if not queue:
            end = "the log was cut at its size bound" if self.truncated else "none left"
            raise ReplayDiverged(f"replay of {self.path}: {instrument} call {index} ({what}): "
                                 f"not in the recording ({end})")
        record = queue[0]
        if record["k"] != kind:
            raise ReplayDiverged(f"replay of {self.path}: {instrument} call {index} at "
                                 f"recorded host time {record['t']:.6f} s: the driver made "
                                 f"a {kind} ({what}), the recording has a {record['k']} "
                                 f"({_describe(record)})")
        queue.popleft()
        self._served[instrument] = index + 1
        self._follow(record.get("s", record["t"]), record["t"], clock)
        return record

    def diverged(self, instrument: str, record: dict[str, Any], what: str) -> ReplayDiverged:
        index = self._served.get(instrument, 1) - 1
        return ReplayDiverged(f"replay of {self.path}: {instrument} call {index} at recorded "
                              f"host time {record['t']:.6f} s: the driver sent {what}, the "
                              f"recording has {_describe(record)}")

    def _follow(self, start: float, t: float, clock: Clock) -> None:
        """Move a virtual clock to the recorded end of the call, on the recording's time
        base shifted to where this replay's first call began."""
        if not isinstance(clock, VirtualClock):
            return
        if self._offset is None:
            self._offset = start - clock.now()
        target = t - self._offset
        if target > clock.now():
            clock.sleep_until(target)


def _describe(record: dict[str, Any]) -> str:
    kind = record["k"]
    if kind in ("write", "read"):
        return f"{kind} {record.get('b', '')!r}"
    if kind in ("writeline", "readline", "readlines"):
        return f"{kind} {record.get('l', '')!r}"
    if kind == "rpc":
        return f"rpc {record.get('m')} request {record.get('q', '')[:64]!r}"
    return f"{kind} {record.get('n', '')}"


_active: WireLog | Replay | None = None
_suspended = 0
_state_lock = threading.Lock()


def active() -> WireLog | Replay | None:
    """The log being written or replayed, None when neither (or suspended)."""
    return None if _suspended else _active


@contextlib.contextmanager
def recording(log: WireLog) -> Iterator[WireLog]:
    """Record every link opened while active into ``log`` (closed at the end)."""
    global _active
    with _state_lock:
        previous, _active = _active, log
    try:
        yield log
    finally:
        with _state_lock:
            _active = previous
        log.close()


@contextlib.contextmanager
def replaying(replay: Replay) -> Iterator[Replay]:
    """Serve every link opened while active from ``replay``."""
    global _active
    with _state_lock:
        previous, _active = _active, replay
    try:
        yield replay
    finally:
        with _state_lock:
            _active = previous


@contextlib.contextmanager
def suspended() -> Iterator[None]:
    """Links opened meanwhile are neither recorded nor replayed (the rehearsal's twin)."""
    global _suspended
    with _state_lock:
        _suspended += 1
    try:
        yield
    finally:
        with _state_lock:
            _suspended -= 1


# ---- serial ports (the KDC101) ------------------------------------------------------------

class RecordingPort:
    """A pyserial port whose calls are logged (attributes pass through)."""

    def __init__(self, port: Any, log: WireLog, name: str, clock: Clock):
        object.__setattr__(self, "_inner", port)
        object.__setattr__(self, "_log", log)
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_clock", clock)

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._inner, attr)

    def __setattr__(self, attr: str, value: Any) -> None:
        setattr(self._inner, attr, value)

    def _add(self, kind: str, start: float, **fields: Any) -> None:
        self._log.add(self._name, kind, start, self._clock.now(), **fields)

    def write(self, data: bytes) -> int | None:
        start = self._clock.now()
        out = self._inner.write(data)
        self._add("write", start, b=bytes(data).hex())
        return out

    def read(self, size: int = 1) -> bytes:
        start = self._clock.now()
        data = bytes(self._inner.read(size))
        self._add("read", start, b=data.hex())
        return data

    @property
    def in_waiting(self) -> int:
        start = self._clock.now()
        n = int(self._inner.in_waiting)
        self._add("waiting", start, n=n)
        return n

    def reset_input_buffer(self) -> None:
        start = self._clock.now()
        self._inner.reset_input_buffer()
        self._add("purge", start, n=0)

    def reset_output_buffer(self) -> None:
        start = self._clock.now()
        self._inner.reset_output_buffer()
        self._add("purge", start, n=1)


class ReplayPort:
    """A stand-in port answering from a :class:`Replay`."""

    def __init__(self, replay: Replay, name: str, clock: Clock, port: str = "replay"):
        self._replay, self._name, self._clock = replay, name, clock
        self.port = port
        self.is_open = True
        self.timeout: float | None = 0
        self.rts = self.rtscts = False

    def open(self) -> None:
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def write(self, data: bytes) -> int:
        record = self._replay.next(self._name, "write", f"write {bytes(data).hex()!r}",
                                   self._clock)
        if record["b"] != bytes(data).hex():
            raise self._replay.diverged(self._name, record, f"write {bytes(data).hex()!r}")
        return len(data)

    def read(self, size: int = 1) -> bytes:
        record = self._replay.next(self._name, "read", f"read of {size}", self._clock)
        return bytes.fromhex(record["b"])

    @property
    def in_waiting(self) -> int:
        return int(self._replay.next(self._name, "waiting", "in_waiting", self._clock)["n"])

    def reset_input_buffer(self) -> None:
        self._replay.next(self._name, "purge", "input purge", self._clock)

    def reset_output_buffer(self) -> None:
        self._replay.next(self._name, "purge", "output purge", self._clock)


def serial_port(name: str, clock: Clock, open_port: Callable[[], T]) -> T:
    """The driver's port: opened by ``open_port``, recorded, or replayed instead."""
    state = active()
    if isinstance(state, Replay):
        return ReplayPort(state, name, clock)  # type: ignore[return-value]
    port = open_port()
    if isinstance(state, WireLog):
        return RecordingPort(port, state, name, clock)  # type: ignore[return-value]
    return port


# ---- gRPC channels (the USB-6001) ---------------------------------------------------------

def _rpc_error_fields(exc: BaseException) -> dict[str, Any]:
    code = getattr(exc, "code", None)
    details = getattr(exc, "details", None)
    trailing = getattr(exc, "trailing_metadata", None)
    return {"code": code().name if callable(code) and code() is not None else "UNKNOWN",
            "details": details() if callable(details) else str(exc),
            "trailing": [list(m) for m in (trailing() or ())] if callable(trailing) else []}


class _RecordingCall:
    def __init__(self, inner: Any, method: str, serialize: Callable[[Any], bytes] | None,
                 log: WireLog, name: str, clock: Clock):
        self.inner, self.method, self.serialize = inner, method, serialize
        self.log, self.name, self.clock = log, name, clock

    def _bytes(self, message: Any) -> str:
        if self.serialize is not None:
            return bytes(self.serialize(message)).hex()
        return bytes(message.SerializeToString()).hex()

    def _call(self, fn: Callable[[], T], request: Any, pick: Callable[[T], Any]) -> T:
        start = self.clock.now()
        try:
            out = fn()
        except Exception as exc:
            self.log.add(self.name, "rpc", start, self.clock.now(), m=self.method,
                         q=self._bytes(request), e=_rpc_error_fields(exc))
            raise
        response = pick(out)
        self.log.add(self.name, "rpc", start, self.clock.now(), m=self.method,
                     q=self._bytes(request), r=bytes(response.SerializeToString()).hex())
        return out

    def __call__(self, request: Any, *args: Any, **kwargs: Any) -> Any:
        return self._call(lambda: self.inner(request, *args, **kwargs), request, lambda r: r)

    def with_call(self, request: Any, *args: Any, **kwargs: Any) -> Any:
        return self._call(lambda: self.inner.with_call(request, *args, **kwargs), request,
                          lambda pair: pair[0])


class RecordingChannel:
    """A gRPC channel look-alike logging each unary call of the channel it wraps."""

    def __init__(self, channel: Any, log: WireLog, name: str, clock: Clock):
        self.channel, self.log, self.name, self.clock = channel, log, name, clock

    def unary_unary(self, method: str, request_serializer: Any = None,
                    response_deserializer: Any = None, *args: Any, **kwargs: Any) -> Any:
        inner = self.channel.unary_unary(method, request_serializer, response_deserializer,
                                         *args, **kwargs)
        return _RecordingCall(inner, method, request_serializer, self.log, self.name,
                              self.clock)

    def __getattr__(self, attr: str) -> Any:
        return getattr(self.channel, attr)


class ReplayRpcError(Exception):
    """A recorded RPC failure, raised again with its status, details and trailing metadata."""

    def __init__(self, fields: dict[str, Any]):
        super().__init__(fields.get("details", ""))
        self.fields = fields

    def code(self) -> Any:
        import grpc

        return getattr(grpc.StatusCode, self.fields.get("code", "UNKNOWN"))

    def details(self) -> str:
        return str(self.fields.get("details", ""))

    def trailing_metadata(self) -> tuple[tuple[str, str], ...]:
        return tuple((k, v) for k, v in self.fields.get("trailing", ()))

    def result(self) -> Any:
        raise self


class _ReplayCall:
    def __init__(self, replay: Replay, method: str, serialize: Callable[[Any], bytes] | None,
                 deserialize: Callable[[bytes], Any] | None, name: str, clock: Clock):
        self.replay, self.method, self.name, self.clock = replay, method, name, clock
        self.serialize, self.deserialize = serialize, deserialize

    def __call__(self, request: Any, *args: Any, **kwargs: Any) -> Any:
        sent = bytes(self.serialize(request) if self.serialize is not None
                     else request.SerializeToString()).hex()
        record = self.replay.next(self.name, "rpc", f"rpc {self.method}", self.clock)
        if record["m"] != self.method or record["q"] != sent:
            raise self.replay.diverged(self.name, record, f"rpc {self.method} request "
                                       f"{sent[:64]!r}")
        if "e" in record:
            raise _replay_error(record["e"])
        if self.deserialize is None:
            raise ReplayDiverged(f"replay: {self.method} has no response type to decode")
        return self.deserialize(bytes.fromhex(record["r"]))

    def with_call(self, request: Any, *args: Any, **kwargs: Any) -> tuple[Any, _ReplayCall]:
        return self(request), self


def _replay_error(fields: dict[str, Any]) -> Exception:
    import grpc

    class _Error(ReplayRpcError, grpc.RpcError):
        pass

    return _Error(fields)


class ReplayChannel:
    """A gRPC channel look-alike answering from a :class:`Replay`."""

    def __init__(self, replay: Replay, name: str, clock: Clock):
        self.replay, self.name, self.clock = replay, name, clock

    def unary_unary(self, method: str, request_serializer: Any = None,
                    response_deserializer: Any = None, *args: Any, **kwargs: Any) -> Any:
        return _ReplayCall(self.replay, method, request_serializer, response_deserializer,
                           self.name, self.clock)

    def _streaming(self, method: str, *args: Any, **kwargs: Any) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            raise ReplayDiverged(f"replay: streaming call {method} is not recorded")

        return call

    unary_stream = stream_unary = stream_stream = _streaming

    def subscribe(self, *args: Any, **kwargs: Any) -> None:
        """Always ready."""

    def unsubscribe(self, *args: Any, **kwargs: Any) -> None:
        """See :meth:`subscribe`."""

    def close(self) -> None:
        """Nothing to release."""


def grpc_channel(name: str, clock: Clock, channel: T) -> T:
    """The driver's channel: itself, recorded, or replayed instead."""
    state = active()
    if isinstance(state, Replay):
        return ReplayChannel(state, name, clock)  # type: ignore[return-value]
    if isinstance(state, WireLog) and channel is not None:
        return RecordingChannel(channel, state, name, clock)  # type: ignore[return-value]
    return channel


# ---- line transports (the MCR 501) --------------------------------------------------------

def _error_fields(exc: BaseException) -> dict[str, str]:
    return {"type": type(exc).__name__, "text": str(exc)}


def _raise_recorded(fields: dict[str, str]) -> None:
    from gelrig.instrument.core import errors

    kind = getattr(errors, fields.get("type", ""), None)
    if not (isinstance(kind, type) and issubclass(kind, Exception)):
        kind = errors.InstrumentError
    raise kind(fields.get("text", ""))


class RecordingLines:
    """A line transport whose lines (and failures) are logged."""

    def __init__(self, inner: Any, log: WireLog, name: str, clock: Clock):
        self.inner, self.log, self.name, self.clock = inner, log, name, clock

    def __getattr__(self, attr: str) -> Any:
        return getattr(self.inner, attr)

    def _logged(self, kind: str, fn: Callable[[], T], **fields: Any) -> T:
        start = self.clock.now()
        try:
            out = fn()
        except Exception as exc:
            self.log.add(self.name, kind, start, self.clock.now(), e=_error_fields(exc),
                         **fields)
            raise
        result = {"l": out} if kind in ("readline", "readlines") else {}
        self.log.add(self.name, kind, start, self.clock.now(), **fields, **result)
        return out

    def write_line(self, line: str) -> None:
        self._logged("writeline", lambda: self.inner.write_line(line), l=line)

    def read_line(self) -> str:
        return self._logged("readline", self.inner.read_line)

    def read_lines(self, n: int, min_length: int = 1,
                   rest: Callable[[bytes], int] | None = None) -> list[str]:
        return self._logged("readlines", lambda: self.inner.read_lines(n, min_length, rest),
                            n=n)

    def discard_input(self) -> None:
        self._logged("discard", self.inner.discard_input)

    def reply_timeout(self, seconds: float) -> Any:
        return self.inner.reply_timeout(seconds)

    def close(self) -> None:
        self.inner.close()


class ReplayLines:
    """A line transport answering from a :class:`Replay`."""

    def __init__(self, replay: Replay, name: str, clock: Clock):
        self.replay, self.name, self.clock = replay, name, clock

    def _next(self, kind: str, what: str) -> dict[str, Any]:
        record = self.replay.next(self.name, kind, what, self.clock)
        if "e" in record:
            _raise_recorded(record["e"])
        return record

    def write_line(self, line: str) -> None:
        record = self.replay.next(self.name, "writeline", f"line {line!r}", self.clock)
        if record.get("l") != line:
            raise self.replay.diverged(self.name, record, f"line {line!r}")
        if "e" in record:
            _raise_recorded(record["e"])

    def read_line(self) -> str:
        return str(self._next("readline", "read of a line")["l"])

    def read_lines(self, n: int, min_length: int = 1,
                   rest: Callable[[bytes], int] | None = None) -> list[str]:
        return [str(x) for x in self._next("readlines", f"read of {n} lines")["l"]]

    def discard_input(self) -> None:
        self._next("discard", "discard")

    def reply_timeout(self, seconds: float) -> Any:
        return contextlib.nullcontext()

    def close(self) -> None:
        """Nothing to release."""


def line_transport(name: str, clock: Clock, make: Callable[[], T]) -> T:
    """The driver's line transport: made by ``make``, recorded, or replayed instead."""
    state = active()
    if isinstance(state, Replay):
        return ReplayLines(state, name, clock)  # type: ignore[return-value]
    transport = make()
    if isinstance(state, WireLog):
        return RecordingLines(transport, state, name, clock)  # type: ignore[return-value]
    return transport


__all__ = ["MAX_BYTES", "RecordingChannel", "RecordingLines", "RecordingPort", "Replay",
           "ReplayChannel", "ReplayDiverged", "ReplayLines", "ReplayPort", "WireLog", "active",
           "grpc_channel", "line_transport", "recording", "replaying", "serial_port",
           "suspended"]
