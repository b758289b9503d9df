"""The simulated USB-6001's NI-DAQmx service in process: a channel without sockets.

:class:`InProcessChannel` stands where a ``grpc.Channel`` stands in
``nidaqmx.GrpcSessionOptions``: the official nidaqmx client builds its requests and reads its
responses exactly as over gRPC, and the same :class:`Usb6001Servicer` answers them, but the
call is a direct method call (no serialization, no threads, no loopback). Errors come back as
``grpc.RpcError`` with the same status, details and ``ni-error`` trailing metadata the server
sends. Used by the rig's twin (``gelrig plan``), where only speed differs from the served
simulator; runs keep the gRPC server.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple, NoReturn

import grpc

from gelrig.simulators.usb6001.device import SimulatedUsb6001
from gelrig.simulators.usb6001.servicer import Usb6001Servicer


class _Metadatum(NamedTuple):
    key: str
    value: str


class _Aborted(Exception):
    """Raised by :meth:`_Context.abort`, as grpc's server context does."""


class _Context:
    """The slice of ``grpc.ServicerContext`` the servicer uses: trailing metadata, abort."""

    def __init__(self) -> None:
        self.trailing: tuple[_Metadatum, ...] = ()
        self.code = grpc.StatusCode.OK
        self.details = ""

    def set_trailing_metadata(self, metadata: tuple[tuple[str, str], ...]) -> None:
        self.trailing = tuple(_Metadatum(k, v) for k, v in metadata)

    def abort(self, code: grpc.StatusCode, details: str) -> NoReturn:
        self.code, self.details = code, details
        raise _Aborted(details)


class InProcessRpcError(grpc.RpcError):
    """What a failed call raises: status code, details and trailing metadata, as grpc's."""

    def __init__(self, context: _Context):
        super().__init__(context.details)
        self._context = context

    def code(self) -> grpc.StatusCode:
        return self._context.code

    def details(self) -> str:
        return self._context.details

    def trailing_metadata(self) -> tuple[_Metadatum, ...]:
        return self._context.trailing

    def result(self) -> NoReturn:
        """What grpc's interceptors ask of a failed call: raise it."""
        raise self


class _Unary:
    """A unary multi-callable: plain calls and ``with_call`` (what an interceptor such as the
    driver's deadlines uses); the timeout has nothing to bound in process."""

    def __init__(self, handler: Callable[[Any, _Context], Any]):
        self.handler = handler

    def __call__(self, request: Any, *args: Any, **kwargs: Any) -> Any:
        context = _Context()
        try:
            return self.handler(request, context)
        except _Aborted:
            raise InProcessRpcError(context) from None

    def with_call(self, request: Any, *args: Any, **kwargs: Any) -> tuple[Any, _Unary]:
        return self(request), self


class InProcessChannel:
    """A ``grpc.Channel`` look-alike whose unary calls go straight to a servicer."""

    def __init__(self, device: SimulatedUsb6001):
        self.device = device
        self.servicer = Usb6001Servicer(device)

    def unary_unary(self, method: str, *args: Any, **kwargs: Any) -> _Unary:
        return _Unary(getattr(self.servicer, method.rsplit("/", 1)[-1]))

    def _unsupported(self, method: str, *args: Any, **kwargs: Any) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            context = _Context()
            context.code, context.details = grpc.StatusCode.UNIMPLEMENTED, method
            raise InProcessRpcError(context)

        return call

    unary_stream = stream_unary = stream_stream = _unsupported

    def subscribe(self, *args: Any, **kwargs: Any) -> None:
        """Connectivity callbacks: an in-process channel is always ready."""

    def unsubscribe(self, *args: Any, **kwargs: Any) -> None:
        """See :meth:`subscribe`."""

    def close(self) -> None:
        """Nothing to release."""

    def __enter__(self) -> InProcessChannel:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
