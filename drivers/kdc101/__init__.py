"""Thorlabs KDC101 K-Cube DC servo controller (Z825B actuator) over the APT protocol."""

from gelrig.drivers.kdc101.apt import AptFramer, AptFramingError, Message, MsgId, decode, encode
from gelrig.drivers.kdc101.driver import KDC101

__all__ = ["KDC101", "AptFramer", "AptFramingError", "Message", "MsgId", "decode", "encode"]
