"""pyserial URL handler ``kdc101sim://NAME``: a port wired to an in-process simulator.

Importing this module adds its package to ``serial.protocol_handler_packages``, so
``serial.serial_for_url("kdc101sim://NAME")`` works for any client (our driver, pylablib).
Timeouts are on the simulator's clock: with a virtual clock a read that waits jumps time to
the controller's next message, or to the timeout if none will come, without real waiting.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import serial
from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from gelrig.simulators.kdc101.device import KDC101Simulator, keep_latest

SCHEME = "kdc101sim"
_registry: dict[str, KDC101Simulator] = {}
_registry_lock = threading.Lock()


def register(sim: KDC101Simulator, name: str) -> str:
    """Make ``sim`` reachable as ``kdc101sim://name``; returns the URL."""
    with _registry_lock:
        _registry[name] = sim
    return f"{SCHEME}://{name}"


def unregister(name: str) -> None:
    with _registry_lock:
        _registry.pop(name, None)


def lookup(name: str) -> KDC101Simulator:
    with _registry_lock:
        try:
            return _registry[name]
        except KeyError:
            raise SerialException(
                f"no simulated KDC101 registered as {name!r} (have: {sorted(_registry)})"
            ) from None


class Serial(SerialBase):
    """A pyserial port whose other end is a registered ``KDC101Simulator``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.sim: KDC101Simulator | None = None
        #: the latest writes attempted, even on a dead link (bounded: see keep_latest)
        self.write_log: list[bytes] = []
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:  # type: ignore[has-type]
            raise SerialException("port already open")
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        name = str(self._port).split("://", 1)[-1].strip("/")
        self.sim = lookup(name)
        self.is_open = True

    def close(self) -> None:
        self.is_open = False
        self.sim = None

    def _reconfigure_port(self) -> None:
        """Baud rate, flow control: nothing to do on a simulated wire."""

    def _live(self) -> KDC101Simulator:
        if not self.is_open or self.sim is None:
            raise PortNotOpenError()
        if not self.sim.connected:
            raise SerialException("simulated KDC101 disconnected (device unplugged)")
        return self.sim

    @property
    def in_waiting(self) -> int:
        return self._live().out_waiting()

    def read(self, size: int = 1) -> bytes:
        sim = self._live()
        clock = sim.clock
        timeout = self._timeout
        deadline = math.inf if timeout is None else clock.now() + timeout
        data = bytearray(sim.read(size))
        while len(data) < size:
            if timeout == 0:
                break
            target = min(sim.next_event_time(), deadline)
            if math.isinf(target):
                raise SerialException("read would block forever: the simulator has nothing due")
            if clock.now() >= target:
                if target >= deadline:
                    break
            else:
                clock.sleep_until(target)
            data += self._live().read(size - len(data))
            if clock.now() >= deadline:
                break
        return bytes(data)

    def write(self, data: bytes | bytearray | memoryview) -> int:
        if not self.is_open or self.sim is None:
            raise PortNotOpenError()
        payload = bytes(data)
        self.write_log.append(payload)
        keep_latest(self.write_log)
        self._live().receive(payload)
        return len(payload)

    def flush(self) -> None:
        self._live()

    def reset_input_buffer(self) -> None:
        self._live().discard_output()

    def reset_output_buffer(self) -> None:
        self._live()

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True


def install() -> None:
    """Let ``serial.serial_for_url`` resolve ``kdc101sim://`` (idempotent)."""
    if "gelrig.simulators.kdc101" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("gelrig.simulators.kdc101")


install()
