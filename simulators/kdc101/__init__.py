"""Simulated Thorlabs KDC101 + Z825B speaking APT: in process (``kdc101sim://NAME``) or served
over TCP / a pty (``gelrig sim serve kdc101``)."""

from simulators.kdc101.device import KDC101Simulator, SimConfig
from simulators.kdc101.kinematics import Trajectory, trapezoid_duration
from simulators.kdc101.protocol_kdc101sim import install, register, unregister

install()

__all__ = [
    "KDC101Simulator",
    "SimConfig",
    "Trajectory",
    "install",
    "register",
    "trapezoid_duration",
    "unregister",
]
