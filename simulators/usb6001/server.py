"""Serving the simulated USB-6001 over gRPC: in-process for tests, or as a standalone server."""

from __future__ import annotations

from concurrent import futures
from dataclasses import dataclass

import grpc
from nidaqmx._stubs import nidaqmx_pb2_grpc as pb_grpc

from gelrig.simulators.usb6001.device import SimulatedUsb6001
from gelrig.simulators.usb6001.servicer import MAX_MESSAGE_BYTES, Usb6001Servicer

__all__ = ["MAX_MESSAGE_BYTES", "RunningServer", "start_server"]
_OPTIONS = [
    ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
    ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
]


@dataclass
class RunningServer:
    """A started gRPC server for one simulated device; stop it with :meth:`stop`."""

    server: grpc.Server
    device: SimulatedUsb6001
    host: str
    port: int

    @property
    def address(self) -> str:
        """``host:port`` the server listens on."""
        return f"{self.host}:{self.port}"

    def channel(self) -> grpc.Channel:
        """A new insecure client channel to this server (the caller closes it)."""
        return grpc.insecure_channel(self.address, options=_OPTIONS)

    def stop(self, grace: float | None = None) -> None:
        self.server.stop(grace).wait()

    def __enter__(self) -> RunningServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_server(
    device: SimulatedUsb6001, host: str = "127.0.0.1", port: int = 0, workers: int = 4
) -> RunningServer:
    """Serve ``device`` on ``host:port`` (port 0: an ephemeral one) and return at once."""
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=workers), options=_OPTIONS)
    pb_grpc.add_NiDAQmxServicer_to_server(Usb6001Servicer(device), server)
    bound = server.add_insecure_port(f"{host}:{port}")
    if bound == 0:
        raise OSError(f"cannot listen on {host}:{port}")
    server.start()
    return RunningServer(server, device, host, bound)
