"""Simulated NI USB-6001 served as the NI gRPC Device Server subset the nidaqmx client uses.

In-process, on a shared clock (the plate position comes from the stage simulator)::

    clock = VirtualClock()
    device = compression_daq(clock, plate_position, first_touch=0.004)
    with start_server(device) as server:  # 127.0.0.1, ephemeral port
        sensor = Usb6001ForceSensor(f"grpc://{server.address}", Usb6001Config(),
                                    LoadCellChain(), clock).open()

The names below are imported on first use, so that the configuration
(:mod:`gelrig.simulators.usb6001.config`, what ``gelrig --help`` shows) loads without numpy,
scipy or grpc.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gelrig.simulators.usb6001.device import DeviceSpec, SimulatedUsb6001
    from gelrig.simulators.usb6001.rig import compression_daq
    from gelrig.simulators.usb6001.server import RunningServer, start_server
    from gelrig.simulators.usb6001.signals import (
        ConstantSignal,
        LoadCellSignal,
        SampleCounterSignal,
        SignalSource,
    )

#: public name -> the module (in this package) that defines it
_LAZY = {
    "ConstantSignal": "signals", "DeviceSpec": "device", "LoadCellSignal": "signals",
    "RunningServer": "server", "SampleCounterSignal": "signals", "SignalSource": "signals",
    "SimulatedUsb6001": "device", "compression_daq": "rig", "start_server": "server",
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)


__all__ = [
    "ConstantSignal",
    "DeviceSpec",
    "LoadCellSignal",
    "RunningServer",
    "SampleCounterSignal",
    "SignalSource",
    "SimulatedUsb6001",
    "compression_daq",
    "start_server",
]
