"""Anton Paar MCR 501 rheometer (inter-particle shear rig), over pyvisa.

The command table in :mod:`gelrig.drivers.mcr501.commands` is UNCONFIRMED: the vendor publishes no
command reference, so every entry must be confirmed on the instrument (docs/decisions/0020).
"""

from gelrig.drivers.mcr501.codec import InstrumentTrip, UnknownCommand
from gelrig.drivers.mcr501.driver import MCR501
from gelrig.drivers.mcr501.transport import LineTransport, VisaTransport, open_resource_manager

__all__ = [
    "MCR501",
    "InstrumentTrip",
    "LineTransport",
    "UnknownCommand",
    "VisaTransport",
    "open_resource_manager",
]
