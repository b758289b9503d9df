"""NI-DAQmx failures as gelrig's typed errors, with messages that say what to do."""

from __future__ import annotations

import grpc
import nidaqmx.errors as daq_errors

from gelrig.instrument.contracts.loadcell import AcquisitionOverflowError
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    FramingError,
    GelrigError,
    InstrumentError,
    InstrumentTimeout,
)

#: DAQmx codes that mean acquired samples were lost (buffer or FIFO overflow).
OVERFLOW_CODES = frozenset({-200279, -200010, -200361, -209829})
#: DAQmx codes that mean the named device is not there.
DEVICE_MISSING_CODES = frozenset({-200220, -201003})
SAMPLES_NOT_YET_AVAILABLE = -200284
#: DAQmx code: the device is reserved by another task (here: on the same gRPC server).
RESOURCE_RESERVED = -50103

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


def reserved_help(device: str, server: str | None, session: str) -> str:
    """What to do when ``device`` is reserved by a task gelrig could not reclaim."""
    if server is None:
        return (f"another task on this computer holds {device}: stop the program that runs "
                "it (NI MAX, LabVIEW, another gelrig), or reset the device in NI MAX")
    return (f"another task on the NI gRPC Device Server at {server} holds {device}, not "
            f"gelrig's own session {session!r} (which gelrig reclaims on open): stop the "
            f"program that created it, or restart the NI gRPC Device Server at {server} "
            "(for the simulator: stop and start `gelrig sim serve usb6001` again)")


def translate(exc: Exception, device: str, server: str | None = None,
              session: str = "") -> GelrigError:
    """The gelrig error for an exception raised by the nidaqmx client.

    ``server`` (host:port of the NI gRPC Device Server, None for local NI-DAQmx) and
    ``session`` (gelrig's session name) let messages say which server to restart.
    """
    at = f" on {server}" if server else ""
    if isinstance(exc, daq_errors.DaqNotFoundError | daq_errors.DaqNotSupportedError):
        return DaqDriverNotFoundError(f"USB-6001 {device}: {DRIVER_HELP} ({exc})")
    if isinstance(exc, daq_errors.DaqError):
        code = exc.error_code
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        if code in OVERFLOW_CODES:
            return AcquisitionOverflowError(
                f"USB-6001 {device}: samples were lost, reads fell behind the acquisition "
                f"(DAQmx {code}: {first}); read more often or enlarge the buffer", code)
        if code == RESOURCE_RESERVED:
            return DeviceErrorReply(
                f"USB-6001 {device}: DAQmx {code}, the device is reserved: "
                f"{reserved_help(device, server, session)}", code)
        if code in DEVICE_MISSING_CODES:
            return DaqDeviceNotFoundError(
                f"USB-6001 {device}: no such device (DAQmx {code}: {first}); check the cable "
                "and the device name in NI MAX or the rig file")
        return DeviceErrorReply(f"USB-6001 {device}: DAQmx {code}: {exc}", code)
    if isinstance(exc, daq_errors.RpcError):
        code = exc.rpc_code
        if code == grpc.StatusCode.DEADLINE_EXCEEDED:
            return InstrumentTimeout(
                f"USB-6001 {device}: the NI gRPC Device Server{at} did not answer in time "
                f"(frozen, overloaded or cut off; {exc.description})")
        if code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.CANCELLED):
            return Disconnected(f"USB-6001 {device}: gRPC server{at} unreachable "
                                f"({exc.description})")
        if code in (grpc.StatusCode.INTERNAL, grpc.StatusCode.DATA_LOSS, grpc.StatusCode.UNKNOWN):
            # No DAQmx code came with it: the HTTP/2 exchange itself broke.
            return FramingError(f"USB-6001 {device}: garbled gRPC exchange with the "
                                f"server{at} ({exc.description})")
        return DeviceErrorReply(f"USB-6001 {device}: gRPC {exc}")
    raise TypeError(f"not an nidaqmx error: {exc!r}")


NIDAQMX_ERRORS = (daq_errors.Error,)
