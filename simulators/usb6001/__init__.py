"""Simulated NI USB-6001 served as the NI gRPC Device Server subset the nidaqmx client uses.

In-process, on a shared clock (the plate position comes from the stage simulator)::

    clock = VirtualClock()
    device = compression_daq(clock, plate_position, first_touch=0.004)
    with start_server(device) as server:  # 127.0.0.1, ephemeral port
        sensor = Usb6001ForceSensor(f"grpc://{server.address}", Usb6001Config(),
                                    LoadCellChain(), clock).open()
"""

from simulators.usb6001.device import DeviceSpec, SimulatedUsb6001
from simulators.usb6001.rig import compression_daq
from simulators.usb6001.server import RunningServer, start_server
from simulators.usb6001.signals import (
    ConstantSignal,
    LoadCellSignal,
    SampleCounterSignal,
    SignalSource,
)

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
