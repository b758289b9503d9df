"""Public KDC101 clients gelrig did not write, against the served simulator: pylablib's
``KinesisMotor`` over TCP and thorlabs-apt-device's ``KDC101`` on a pty. Direction is judged by
each client's own position readout (ADR 0100); every session must survive every call (no
unsolicited error replies, ADR 0101). Time is paced (k x real), every wait is bounded."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from gelrig.instrument.core.clock import PacedClock
from gelrig.simulators.kdc101 import KDC101Simulator
from gelrig.simulators.kdc101.config import SimConfig
from gelrig.simulators.kdc101.serve import PtyServer, TcpServer

CPM = 34554.96
MM = round(CPM)
WAIT_S = 10.0  # real-time bound of every wait in this file


def _until(check: Callable[[], bool], what: str, timeout: float = WAIT_S) -> None:
    end = time.monotonic() + timeout
    while not check():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.01)


# ---- pylablib over TCP ---------------------------------------------------------------------
kinesis = pytest.importorskip("pylablib.devices.Thorlabs.kinesis", exc_type=ImportError)


@pytest.fixture(params=["ideal", "documented"])
def tcp(request: pytest.FixtureRequest) -> Iterator[tuple[KDC101Simulator, TcpServer]]:
    # slow enough to see a short move in progress; ideal, or with the documented 16 ms reply
    # and status latency (ADR 0242)
    sim = KDC101Simulator(PacedClock(5.0), SimConfig(timing=request.param))
    server = TcpServer(sim).start()
    yield sim, server
    server.stop()


@pytest.fixture
def motor(tcp: tuple[KDC101Simulator, TcpServer]) -> Iterator[Any]:
    m = kinesis.KinesisMotor(("serial", tcp[1].address), scale="step")
    yield m
    m.close()


def test_pylablib_reads_and_sets_every_kdc101_block(motor: Any, tcp: Any) -> None:
    sim, _ = tcp
    assert motor.get_device_info().model_no == "KDC101"
    info = motor.get_full_info()
    assert info["device_info"].model_no == "KDC101" and info["stage"] == "step"
    status = motor.get_full_status()
    assert status["position"] == motor.get_position() and "enabled" in status["status"]
    settings = motor.get_settings()
    assert {"velocity_parameters", "jog_parameters", "homing_parameters",
            "gen_move_parameters", "limit_switch_parameters", "kcube_trigio_parameters",
            "kcube_trigpos_parameters"} <= set(settings)

    vp = motor.setup_velocity(max_velocity=300000, acceleration=400, scale=False)
    assert (vp.max_velocity, vp.acceleration) == (300000, 400)
    jog = motor.setup_jog(mode="step", step_size=2000, max_velocity=250000, acceleration=300,
                          stop_mode="profiled", scale=False)
    assert (jog.mode, jog.step_size, jog.max_velocity, jog.stop_mode) == (
        "step", 2000, 250000, "profiled")
    assert motor.setup_gen_move(backlash_distance=123, scale=False).backlash_distance == 123
    home = motor.setup_homing(velocity=200000, scale=False)
    assert home.velocity == 200000 and home.home_direction in ("forward", "reverse")
    lim = motor.setup_limit_switch(sw_position_cw=5 * MM, sw_position_ccw=1 * MM, sw_kind="ignore",
                                   scale=False)
    assert (lim.sw_position_cw, lim.sw_position_ccw, lim.sw_kind) == (5 * MM, MM, "ignore")
    trig = motor.setup_kcube_trigio(trig1_mode="out_in_motion", trig1_pol=True)
    assert (trig.trig1_mode, trig.trig1_pol) == ("out_in_motion", True)
    pos = motor.setup_kcube_trigpos(start_fw=100, step_fw=50, num_fw=3, width=1e-4, scale=False)
    assert (pos.start_fw, pos.step_fw, pos.num_fw) == (100, 50, 3)
    assert pos.width == pytest.approx(1e-4)
    # The session is still in step: a plain query after all of that gets its own reply.
    assert motor.get_position() == status["position"]
    assert sim.rejected == []


def test_pylablib_jog_and_moves_go_the_way_its_readout_says(motor: Any) -> None:
    p0 = motor.get_position()
    motor.jog("+")  # continuous: MOT_MOVE_VELOCITY
    assert "moving_fw" in motor.get_status() and "moving_bk" not in motor.get_status()
    time.sleep(0.05)
    motor.stop(sync=True, timeout=WAIT_S)
    p1 = motor.get_position()
    assert p1 > p0
    motor.jog("-")
    assert "moving_bk" in motor.get_status()
    time.sleep(0.05)
    motor.stop(immediate=True, sync=True, timeout=WAIT_S)
    p2 = motor.get_position()
    assert p2 < p1

    motor.move_by(20000)
    st = motor.get_status()
    assert "moving_fw" in st and "moving_bk" not in st
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == p2 + 20000
    motor.move_by(-10000)
    assert "moving_bk" in motor.get_status()
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == p2 + 10000

    motor.setup_jog(mode="step", step_size=15000, scale=False)
    motor.jog("+", kind="builtin")  # MOT_MOVE_JOG, one step
    assert "jogging_fw" in motor.get_status()
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == p2 + 25000
    motor.jog("-", kind="builtin")
    assert "jogging_bk" in motor.get_status()
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == p2 + 10000

    motor.move_to(4 * MM)
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == 4 * MM
    motor.move_to(10 * MM)
    assert motor.is_moving()
    motor.stop(immediate=True, sync=True, timeout=WAIT_S)
    assert not motor.is_moving() and 4 * MM < motor.get_position() < 10 * MM


def test_pylablib_move_to_further_on_mid_move_keeps_the_speed(motor: Any, tcp: Any) -> None:
    """What gelrig's bounded segments rely on (ADR 0201): an absolute target sent while a move
    is under way, further on in the same direction, takes over without slowing down, and the
    stage comes to rest on the last target sent (its own client: pylablib's move_to)."""
    sim, _ = tcp
    motor.setup_velocity(max_velocity=round(1.0 * 772981.3692), acceleration=1055,
                         scale=False)  # 1 mm/s, 4 mm/s^2
    p0 = motor.get_position()
    target = p0 + MM  # 1 mm ahead: it would start to slow down 0.875 mm on
    motor.move_to(target)
    _until(lambda: abs(sim.velocity_at(sim.clock.now())) > 0.999e-3, "the stage to cruise")
    speeds = []
    for _ in range(5):  # renewed 5 times, each 1 mm ahead of where the stage is
        time.sleep(0.06)  # 0.3 s of sim time
        target = motor.get_position() + MM
        motor.move_to(target)
        speeds.append(abs(sim.velocity_at(sim.clock.now())))
        assert "moving_fw" in motor.get_status()
    assert min(speeds) == pytest.approx(1e-3, rel=1e-5)  # no dip at any renewal
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == target
    assert not motor.is_moving()


def test_pylablib_rehome_with_force_waits_for_the_new_homing(motor: Any, tcp: Any) -> None:
    sim, _ = tcp
    motor.home(sync=True, force=False, timeout=WAIT_S)
    assert motor.is_homed() and motor.get_position() == 0
    motor.move_to(2 * MM)
    motor.wait_move(timeout=WAIT_S)
    t0 = sim.clock.now()
    motor.home(sync=True, force=True, timeout=WAIT_S)
    # 2 mm back to the switch at 1 mm/s: it cannot have returned before ~2 s of sim time.
    assert sim.clock.now() - t0 > 2.0
    status = motor.get_status()
    assert "homed" in status and "homing" not in status
    assert motor.get_position() == 0
    motor.move_by(1000)
    motor.wait_move(timeout=WAIT_S)
    assert motor.get_position() == 1000  # the move did not interrupt a homing


def test_second_tcp_client_is_refused_and_the_first_keeps_working(motor: Any, tcp: Any) -> None:
    _, server = tcp
    host, port = server.address.removeprefix("socket://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=WAIT_S) as other:
        other.settimeout(WAIT_S)
        assert other.recv(100) == b""  # closed by the server at once
    assert server.refused == 1
    assert motor.get_device_info().model_no == "KDC101"


# ---- thorlabs-apt-device on a pty -----------------------------------------------------------
tad = pytest.importorskip("thorlabs_apt_device", exc_type=ImportError)


@pytest.fixture(params=["ideal", "documented"])
def stage(request: pytest.FixtureRequest) -> Iterator[tuple[KDC101Simulator, Any]]:
    sim = KDC101Simulator(PacedClock(20.0), SimConfig(timing=request.param))
    server = PtyServer(sim).start()
    dev = tad.KDC101(serial_port=server.address, home=False)  # default invert_direction_logic
    try:
        _until(lambda: dev.status["msgid"] != 0 and dev.velparams["msgid"] != 0,
               "first status and velocity parameters")
        yield sim, dev
    finally:
        dev.close()
        server.stop()


def _settled(dev: Any) -> bool:
    s = dev.status
    return not (s["moving_forward"] or s["moving_reverse"] or s["jogging_forward"]
                or s["jogging_reverse"] or s["homing"])


def _moved_to(dev: Any, counts: int) -> None:
    time.sleep(0.05)  # a few status polls after the command
    _until(lambda: _settled(dev) and dev.status["position"] == counts, f"position {counts}")


def test_thorlabs_apt_device_velocity_move_forward_increases_counts(stage: Any) -> None:
    sim, dev = stage
    assert dev.invert_direction_logic is True
    dev.set_velocity_params(acceleration=400, max_velocity=300000)
    _until(lambda: dev.velparams["max_velocity"] == 300000, "velocity parameters")
    p0 = dev.status["position"]
    dev.move_velocity("forward")
    _until(lambda: dev.status["position"] > p0 + 1000, "forward motion")
    assert dev.status["moving_forward"] and not dev.status["moving_reverse"]
    dev.stop(immediate=True)
    _until(lambda: _settled(dev), "stop")
    p1 = dev.status["position"]
    dev.move_velocity("reverse")
    _until(lambda: dev.status["position"] < p1 - 1000, "reverse motion")
    assert dev.status["moving_reverse"]
    dev.stop()
    _until(lambda: _settled(dev), "stop")
    assert sim.rejected == []


def test_thorlabs_apt_device_jog_and_moves_including_the_short_forms(stage: Any) -> None:
    sim, dev = stage
    p0 = dev.status["position"]
    dev.set_jog_params(size=1200, acceleration=300, max_velocity=250000)
    _until(lambda: dev.jogparams["step_size"] == 1200, "jog parameters")
    dev.move_jog("forward")
    _moved_to(dev, p0 + 1200)
    dev.move_absolute(5000)
    _moved_to(dev, 5000)
    dev.move_relative(-2000)
    _moved_to(dev, 3000)
    dev.move_relative(1500, now=False)  # MOVERELPARAMS, then a header-only MOVE_RELATIVE
    dev.move_relative(now=True)
    _moved_to(dev, 4500)
    dev.move_absolute(700, now=False)  # MOVEABSPARAMS, then a header-only MOVE_ABSOLUTE
    dev.move_absolute(now=True)
    _moved_to(dev, 700)
    assert sim.garbage_received == 0 and sim.rejected == []


def test_thorlabs_apt_device_home_and_enable(stage: Any) -> None:
    sim, dev = stage
    dev.move_absolute(-3000)
    _moved_to(dev, -3000)
    dev.home()
    _until(lambda: dev.status["homed"] and _settled(dev), "homed")
    assert dev.status["position"] == 0
    dev.set_enabled(False)
    _until(lambda: not dev.status["channel_enabled"], "disabled")
    dev.move_absolute(2000)
    time.sleep(0.2)
    assert dev.status["position"] == 0  # a disabled channel does not move
    assert "channel disabled" in sim.rejected[-1][1]
    dev.set_enabled(True)
    _until(lambda: dev.status["channel_enabled"], "enabled")
    dev.move_absolute(2000)
    _moved_to(dev, 2000)
