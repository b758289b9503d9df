"""KDC101 over TCP (pyserial ``socket://``) through a fault proxy, and its served simulator
frozen or killed: each fault is a typed error within the reply timeout, a moving stage is
told to stop first, and the driver recovers or reports Disconnected (ADR 0060)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import pytest

from gelrig.drivers.kdc101 import KDC101
from gelrig.drivers.kdc101.apt import MsgId
from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.clock import RealClock
from gelrig.instrument.core.errors import Disconnected, FramingError, InstrumentTimeout
from gelrig.simulators.kdc101 import KDC101Simulator
from gelrig.simulators.kdc101.serve import TcpServer
from tests.faultproxy import FaultProxy, failing
from tests.served import Served, serve

CONFIG = StageConfig(reply_timeout_s=1.0)
BOUND = CONFIG.reply_timeout_s + 1.5  # the deadline, and a loaded machine


@pytest.fixture
def proxied() -> Iterator[tuple[KDC101Simulator, FaultProxy, KDC101]]:
    clock = RealClock()
    sim = KDC101Simulator(clock)
    server = TcpServer(sim).start()
    port = int(server.address.rsplit(":", 1)[1])
    try:
        with FaultProxy(port, lifetime=60) as proxy:
            stage = KDC101(f"socket://127.0.0.1:{proxy.port}", CONFIG, clock).open()
            try:
                yield sim, proxy, stage
            finally:
                stage.close()
    finally:
        server.stop()



def eventually(check: Callable[[], bool], within: float = 1.0) -> bool:
    """``check()`` became true within ``within`` seconds (polled)."""
    end = time.monotonic() + within
    while not check():
        if time.monotonic() > end:
            return False
        time.sleep(0.01)
    return True


@pytest.mark.parametrize(("fault", "error"), [
    ("swallow", InstrumentTimeout),
    ("garbage", FramingError),  # was 4.0 s at a 2 s reply timeout (two full waits)
    ("truncate", FramingError),
])
def test_wire_fault_mid_move_stops_first_then_raises_within_the_deadline(
        proxied: tuple[KDC101Simulator, FaultProxy, KDC101], fault: str,
        error: type[Exception]) -> None:
    sim, proxy, stage = proxied
    stage.move_by(2e-3, wait=False)  # ~1 s of motion at 2.3 mm/s
    getattr(proxy, fault)()
    _, took = failing(stage.wait_until_stopped, error)
    assert took < BOUND, took
    # The stop went out first (the server may take a moment to read it).
    assert eventually(lambda: sim.received[-1].msg_id == MsgId.MOT_MOVE_STOP)
    assert eventually(lambda: sim.velocity_at(sim.clock.now()) == 0.0)
    proxy.heal()
    assert not stage.status().busy  # back in step


def test_a_reply_later_than_the_timeout_is_a_timeout(
        proxied: tuple[KDC101Simulator, FaultProxy, KDC101]) -> None:
    _, proxy, stage = proxied
    proxy.delay(0.2)
    assert stage.position_counts() == stage.position_counts()  # slow but in time
    proxy.delay(CONFIG.reply_timeout_s + 2.0)
    assert failing(stage.position_counts, InstrumentTimeout)[1] < BOUND


def test_closed_connection_mid_move_is_a_disconnection(
        proxied: tuple[KDC101Simulator, FaultProxy, KDC101]) -> None:
    sim, proxy, stage = proxied
    stage.move_by(2e-3, wait=False)
    proxy.close()
    assert failing(stage.wait_until_stopped, Disconnected)[1] < BOUND
    proxy.heal()
    # The simulator, like a serial port in use, closes a second client until it has noticed
    # the first one gone (its next poll): reopen as the safe stop does, a few bounded tries.
    deadline = time.monotonic() + 5.0
    while True:
        try:
            again = KDC101(f"socket://127.0.0.1:{proxy.port}", CONFIG, sim.clock).open()
            break
        except Disconnected:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)
    with again:
        again.stop()
        assert not again.status().busy


@pytest.fixture
def served() -> Iterator[Served]:
    with serve("kdc101", duration=120) as s:
        yield s


def test_sigstopped_server_is_a_timeout_within_the_deadline(served: Served) -> None:
    stage = KDC101(f"socket://127.0.0.1:{served.port}", CONFIG, RealClock()).open()
    try:
        served.pause()
        try:
            assert failing(stage.position, InstrumentTimeout)[1] < BOUND
        finally:
            served.resume()
    finally:
        stage.close()


def test_killed_server_is_a_disconnection_within_the_deadline(served: Served) -> None:
    stage = KDC101(f"socket://127.0.0.1:{served.port}", CONFIG, RealClock()).open()
    try:
        stage.move_by(1e-3, wait=False)
        served.kill()
        _, took = failing(stage.wait_until_stopped, (Disconnected, InstrumentTimeout))
        assert took < BOUND, took
    finally:
        stage.close()



LATE = CONFIG.reply_timeout_s + 0.4  # a reply delay beyond the deadline (s)


def slower(stage: KDC101) -> None:
    """Set a new velocity: the driver reads the parameters back and compares."""
    stage.set_velocity(stage.max_velocity_m_s / 2, stage.acceleration_m_s2)


def test_a_late_reply_is_not_taken_for_the_next_requests_reply(
        proxied: tuple[KDC101Simulator, FaultProxy, KDC101]) -> None:
    """APT replies carry no request id: the reply to a timed-out read, arriving after the
    next read of the same kind went out, must not be taken for that read's reply (here the
    old velocity parameters would fail the read-back of new ones)."""
    _, proxy, stage = proxied
    proxy.delay(LATE)
    failing(stage.velocity_params, InstrumentTimeout)  # its reply is still on its way
    proxy.heal()  # the late reply is delivered first, then the fresh ones (in order)
    slower(stage)
    assert stage.velocity_params().max_velocity == stage.config.apt_velocity(
        stage.max_velocity_m_s)
    assert stage.stale_replies == 1
    assert stage.position_counts() == stage.position_counts()  # in step


def test_a_frozen_controller_that_resumes_answers_in_step(served: Served) -> None:
    """SIGSTOP, a read times out, SIGCONT: the resumed server answers the old read at once;
    the driver drops that answer and reads the new velocity parameters back."""
    stage = KDC101(f"socket://127.0.0.1:{served.port}", CONFIG, RealClock()).open()
    try:
        served.pause()
        try:
            assert failing(stage.velocity_params, InstrumentTimeout)[1] < BOUND
        finally:
            served.resume()
        slower(stage)  # fails if the old read's reply is taken for the read-back
        # the late reply is either still in flight (dropped by the resync: counted) or
        # already buffered when the next request starts (discarded with the input)
        assert stage.stale_replies <= 1
        assert not stage.status().busy
    finally:
        stage.close()
