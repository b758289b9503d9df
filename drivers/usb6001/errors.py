"""NI-DAQmx failures as gelrig's typed errors, with messages that say what to do."""

from __future__ import annotations

import grpc
import nidaqmx.errors as daq_errors

from instrument.errors import DeviceErrorReply, Disconnected, GelrigError, InstrumentError
from instrument.loadcell import AcquisitionOverflowError

#: DAQmx codes that mean acquired samples were lost (buffer or FIFO overflow).
OVERFLOW_CODES = frozenset({-200279, -200010, -200361, -209829})
#: DAQmx codes that mean the named device is not there.
DEVICE_MISSING_CODES = frozenset({-200220, -201003})
SAMPLES_NOT_YET_AVAILABLE = -200284

DRIVER_HELP = (
    "the NI-DAQmx driver is not installed on this computer. Install NI-DAQmx "
    "(`python -m nidaqmx installdriver`, or from ni.com) to use a USB-6001 here, or use the "
    "simulator: run `gelrig sim serve usb6001 --port PORT` and give the instrument the "
    "address grpc://HOST:PORT"
)


class DaqDriverNotFoundError(InstrumentError):
    """The NI-DAQmx C driver is missing (nidaqmx's DaqNotFoundError, not a DaqError)."""


class DaqDeviceNotFoundError(InstrumentError):
    """The named DAQ device is not present (unplugged, renamed, or another name)."""


def translate(exc: Exception, device: str) -> GelrigError:
    """The gelrig error for an exception raised by the nidaqmx client."""
    if isinstance(exc, daq_errors.DaqNotFoundError | daq_errors.DaqNotSupportedError):
        return DaqDriverNotFoundError(f"USB-6001 {device}: {DRIVER_HELP} ({exc})")
    if isinstance(exc, daq_errors.DaqError):
        code = exc.error_code
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        if code in OVERFLOW_CODES:
            return AcquisitionOverflowError(
                f"USB-6001 {device}: samples were lost, reads fell behind the acquisition "
                f"(DAQmx {code}: {first}); read more often or enlarge the buffer", code)
        if code in DEVICE_MISSING_CODES:
            return DaqDeviceNotFoundError(
                f"USB-6001 {device}: no such device (DAQmx {code}: {first}); check the cable "
                "and the device name in NI MAX or the rig file")
        return DeviceErrorReply(f"USB-6001 {device}: DAQmx {code}: {exc}", code)
    if isinstance(exc, daq_errors.RpcError):
        if exc.rpc_code == grpc.StatusCode.UNAVAILABLE:
            return Disconnected(f"USB-6001 {device}: gRPC server unreachable ({exc.description})")
        return DeviceErrorReply(f"USB-6001 {device}: gRPC {exc}")
    raise TypeError(f"not an nidaqmx error: {exc!r}")


NIDAQMX_ERRORS = (daq_errors.Error,)
