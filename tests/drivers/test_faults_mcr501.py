"""MCR 501 over pyvisa-py TCP through a fault proxy, and its served simulator frozen or killed:
each fault is a typed error within the reply timeout (plus a bounded stop), the arm is told to
stop first, and the driver recovers or reports Disconnected (ADR 0060)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest

from gelrig.drivers.mcr501 import MCR501
from gelrig.drivers.mcr501.driver import STOP_ACK_TIMEOUT_S
from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.clock import RealClock, VirtualClock
from gelrig.instrument.core.errors import Disconnected, FramingError, InstrumentTimeout
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig, SimulatorServer
from tests.faultproxy import FaultProxy, failing
from tests.served import Served, serve

TIMEOUT = 1.5
CONFIG = RheometerConfig(timeout=TIMEOUT)
#: The reply deadline, the bounded stop after it, and a loaded machine (a stop that waited a
#: whole reply timeout, as before ADR 0060, exceeds it).
BOUND = TIMEOUT + STOP_ACK_TIMEOUT_S + 0.7


@pytest.fixture
def proxied(rm: Any) -> Iterator[tuple[MCR501Simulator, FaultProxy, MCR501]]:
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True))
    with SimulatorServer(sim) as server, FaultProxy(server.port, lifetime=60) as proxy:
        drv = MCR501(f"TCPIP0::127.0.0.1::{proxy.port}::SOCKET", clock, CONFIG,
                     resource_manager=rm).open()
        try:
            yield sim, proxy, drv
        finally:
            drv.close()



@pytest.mark.parametrize(("fault", "error"), [
    ("swallow", InstrumentTimeout),
    ("garbage", (FramingError, InstrumentTimeout)),
    ("truncate", (FramingError, InstrumentTimeout)),
])
def test_wire_fault_while_turning_stops_first_then_raises_within_the_deadline(
        proxied: tuple[MCR501Simulator, FaultProxy, MCR501], fault: str,
        error: type[Exception] | tuple[type[Exception], ...]) -> None:
    sim, proxy, drv = proxied
    drv.rotate(1e-3)
    getattr(proxy, fault)()
    _, took = failing(drv.torque, error)
    assert took < BOUND, took
    assert sim.log[-1] == ":STOP[]"  # the stop got through, though its answer did not
    assert sim.cell.spin.target == 0.0
    proxy.heal()
    assert drv.identify().model == "MCR501"  # back in step


def test_a_reply_later_than_the_timeout_is_a_timeout(
        proxied: tuple[MCR501Simulator, FaultProxy, MCR501]) -> None:
    _, proxy, drv = proxied
    proxy.delay(0.2)
    assert drv.identify().model == "MCR501"  # slow but in time
    proxy.delay(TIMEOUT + 2.0)
    assert failing(drv.gap, InstrumentTimeout)[1] < BOUND


def test_closed_connection_is_a_disconnection(
        proxied: tuple[MCR501Simulator, FaultProxy, MCR501], rm: Any) -> None:
    sim, proxy, drv = proxied
    drv.rotate(1e-3)
    proxy.close()
    assert failing(drv.torque, Disconnected)[1] < BOUND
    proxy.heal()
    again = MCR501(f"TCPIP0::127.0.0.1::{proxy.port}::SOCKET", sim.clock, CONFIG,
                   resource_manager=rm).open()
    again.stop()
    again.close()
    assert sim.cell.spin.target == 0.0


@pytest.fixture
def served() -> Iterator[Served]:
    with serve("mcr501", duration=120) as s:
        yield s


def _served_driver(s: Served, rm: Any) -> MCR501:
    return MCR501(f"TCPIP0::127.0.0.1::{s.port}::SOCKET", RealClock(), CONFIG,
                  resource_manager=rm).open()


def test_sigstopped_server_is_a_timeout_within_the_deadline_then_recovers(
        served: Served, rm: Any) -> None:
    drv = _served_driver(served, rm)
    try:
        drv.rotate(1e-3)
        served.pause()
        try:
            _, took = failing(drv.torque, InstrumentTimeout)  # was 6.1 s at timeout 2 s
            assert took < BOUND, took
            t0 = time.monotonic()
            drv.close()  # the stop on close is bounded too
            assert time.monotonic() - t0 < BOUND
        finally:
            served.resume()
        time.sleep(0.3)  # the frozen server's late replies arrive
        drv = _served_driver(served, rm)
        assert drv.status().mode != "rotating"  # the stops sent while frozen got through
    finally:
        drv.close()


def test_killed_server_is_a_disconnection_within_the_deadline(served: Served, rm: Any) -> None:
    drv = _served_driver(served, rm)
    try:
        drv.rotate(1e-3)
        served.kill()
        assert failing(drv.torque, Disconnected)[1] < BOUND
    finally:
        drv.close()
