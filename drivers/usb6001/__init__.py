"""NI USB-6001 load-cell input through the official nidaqmx API (local or gRPC)."""

from gelrig.drivers.usb6001.config import Usb6001Config
from gelrig.drivers.usb6001.errors import DaqDeviceNotFoundError, DaqDriverNotFoundError
from gelrig.drivers.usb6001.sensor import Usb6001ForceSensor, grpc_options_for

__all__ = [
    "DaqDeviceNotFoundError",
    "DaqDriverNotFoundError",
    "Usb6001Config",
    "Usb6001ForceSensor",
    "grpc_options_for",
]
