"""The USB-6001 force input's configuration (defined in gelrig.instrument.contracts.daq, which the
rig file
reader uses without importing the driver)."""

from __future__ import annotations

from gelrig.instrument.contracts.daq import (
    MIN_RATE,
    OVER_RANGE_POLICIES,
    RANGE_VOLTS,
    TERMINALS,
    Usb6001Config,
)

__all__ = ["MIN_RATE", "OVER_RANGE_POLICIES", "RANGE_VOLTS", "TERMINALS", "Usb6001Config"]
