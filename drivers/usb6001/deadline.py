"""A deadline on every gRPC call the nidaqmx client makes (ADR 0060).

nidaqmx's gRPC interpreter calls each RPC without a timeout (``func(request, metadata=...)``),
so a frozen NI gRPC Device Server blocks the caller for good. The channel the driver builds is
wrapped with :class:`DeadlineInterceptor`, which gives each call ``call_timeout`` seconds plus
the request's own wait (``timeout`` of ReadAnalogF64 and the like), and never more than what is
left of an operation's :meth:`~DeadlineInterceptor.budget` (open and close, which make several
calls, so that a dead server costs one deadline, not one per call).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, NamedTuple

import grpc

#: Shortest deadline given to a call once a budget is spent (s): it fails at once.
SPENT_S = 1e-3


class _CallDetails(NamedTuple):
    method: str
    timeout: float | None
    metadata: Any
    credentials: Any
    wait_for_ready: Any
    compression: Any


class CallDetails(_CallDetails, grpc.ClientCallDetails):
    """``grpc.ClientCallDetails`` with a new timeout."""


class DeadlineInterceptor(grpc.UnaryUnaryClientInterceptor):
    """Sets ``timeout`` on every unary call through the channel it wraps.

    Streaming calls (DAQmx event streams, long-lived by design and unused by gelrig) pass as
    they are.
    """

    def __init__(self, call_timeout: float):
        if not (math.isfinite(call_timeout) and call_timeout > 0):
            raise ValueError(f"call_timeout must be > 0 s, got {call_timeout!r}")
        self.call_timeout = call_timeout
        self._budget_end: float | None = None
        self.last_timeout: float | None = None  # the deadline the last call got (s)

    def timeout_for(self, request: object) -> float:
        """``call_timeout`` plus the request's own wait, capped by the current budget."""
        seconds = self.call_timeout
        wait = getattr(request, "timeout", None)
        if isinstance(wait, float) and math.isfinite(wait) and wait > 0:
            seconds += wait
        if self._budget_end is not None:
            seconds = min(seconds, max(SPENT_S, self._budget_end - time.monotonic()))
        return seconds

    @contextmanager
    def budget(self, seconds: float) -> Iterator[None]:
        """Every call in the block ends by ``seconds`` from now (nested budgets: the tighter)."""
        before = self._budget_end
        end = time.monotonic() + seconds
        self._budget_end = end if before is None else min(before, end)
        try:
            yield
        finally:
            self._budget_end = before

    def _details(self, details: grpc.ClientCallDetails, request: object) -> CallDetails:
        seconds = self.timeout_for(request)
        if details.timeout is not None:
            seconds = min(seconds, details.timeout)
        self.last_timeout = seconds
        return CallDetails(details.method, seconds, details.metadata, details.credentials,
                           getattr(details, "wait_for_ready", None),
                           getattr(details, "compression", None))

    def intercept_unary_unary(self, continuation: Callable[..., Any],
                              client_call_details: grpc.ClientCallDetails,
                              request: object) -> Any:
        return continuation(self._details(client_call_details, request), request)


def with_deadlines(channel: grpc.Channel, interceptor: DeadlineInterceptor) -> grpc.Channel:
    """``channel`` with every call bounded by ``interceptor``."""
    return grpc.intercept_channel(channel, interceptor)
