"""Faults and bad input: typed errors, and the arm stopped before the error reaches the caller.

Driver against the simulator through pyvisa-py over TCP, in virtual time.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from gelrig.drivers.mcr501 import InstrumentTrip, UnknownCommand
from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import (
    DeviceErrorReply,
    Disconnected,
    FramingError,
    InstrumentTimeout,
    LimitError,
)
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig
from tests.drivers.mcr501_harness import Rig
from tests.drivers.mcr501_harness import rig as _rig


def rig(rm: Any, sim_config: SimConfig | None = None, config: RheometerConfig | None = None) -> Any:
    """The shared harness, with the gap already referenced unless told otherwise."""
    return _rig(rm, sim_config if sim_config is not None else SimConfig(start_referenced=True),
                config)


def _spin(r: Rig, speed: float = 1e-3) -> None:
    r.drv.rotate(speed)
    r.turn(0.9)  # past the ramp; the next request is not a renewal (due 0.5 s after the last)
    assert r.drv.maybe_rotating


def test_unknown_command_stops_rotation(rm: Any) -> None:
    with rig(rm) as r:
        _spin(r)
        r.sim.faults.reject("read_torque")
        with pytest.raises(UnknownCommand) as err:
            r.drv.torque()
        assert isinstance(err.value, DeviceErrorReply) and err.value.code == 10
        assert ":TORQ" in str(err.value)
        assert r.sim.log[-1] == ":STOP[]"
        assert not r.drv.maybe_rotating
        assert r.arm_stopped()


def test_malformed_reply_raises_framing_error_and_stops(rm: Any) -> None:
    with rig(rm) as r:
        _spin(r)
        r.sim.faults.mangle_next()
        with pytest.raises(FramingError, match="malformed reply to read_angle"):
            r.drv.angle()
        assert r.sim.log[-1] == ":STOP[]"
        assert r.arm_stopped()
        assert r.drv.identify().model == "MCR501"  # back in step after the fault


def test_timeout_raises_and_stops(rm: Any) -> None:
    with rig(rm, config=RheometerConfig(timeout=0.3)) as r:
        _spin(r, -1e-3)
        r.sim.faults.silence_next()
        with pytest.raises(InstrumentTimeout, match=r"no reply within 0\.3 s"):
            r.drv.torque()
        assert r.sim.log[-1] == ":STOP[]"
        assert not r.drv.maybe_rotating
        assert r.arm_stopped()
        assert r.drv.status().mode == "idle"


def test_disconnect_raises_disconnected(rm: Any) -> None:
    with rig(rm, config=RheometerConfig(timeout=0.3)) as r:
        _spin(r)
        assert r.server.disconnect_clients() == 1
        with pytest.raises(Disconnected):
            r.drv.torque()
        # the stop could not be delivered, so the driver still treats the arm as turning
        assert r.drv.maybe_rotating


def _deep_gap_setup(r: Rig, overlap: float) -> None:
    """Gap for ``overlap`` while the arm is far from the lower sphere."""
    r.drv.set_gap(r.sim.config.touch_gap - overlap)
    assert r.sim.cell.forces(r.clock.now()).delta < 0


def test_torque_over_range_trips_the_instrument(rm: Any) -> None:
    sim_cfg = SimConfig(start_referenced=True, torque_range=1e-4)
    with rig(rm, sim_cfg) as r:
        _deep_gap_setup(r, 0.78e-3)
        _spin(r, 1e-3)
        with pytest.raises(InstrumentTrip) as err:
            for _ in range(100_000):
                r.drv.torque()
                r.clock.sleep(0.2)
        assert err.value.code == 32
        assert "torque over range" in str(err.value)
        assert r.sim.log[-1] == ":STOP[]"
        trip = r.sim.cell.trips[0]
        # the arm stopped dead at the trip, not where the host noticed it
        assert r.drv.angle() == pytest.approx(trip.angle, abs=1e-8)
        assert r.arm_stopped()
        assert r.drv.status().fault


def test_overlap_limit_trips_while_rotating_into_the_sphere(rm: Any) -> None:
    sim_cfg = SimConfig(start_referenced=True, overlap_limit=0.5e-3)
    with rig(rm, sim_cfg) as r:
        _deep_gap_setup(r, 0.78e-3)
        _spin(r, 2e-3)
        with pytest.raises(InstrumentTrip) as err:
            for _ in range(100_000):
                r.drv.normal_force()
                r.clock.sleep(0.2)
        assert err.value.code == 31
        delta = r.sim.cell.overlap(np.array([r.clock.now()]))[0]
        assert delta == pytest.approx(0.5e-3, abs=2e-6)
        assert r.sim.log[-1] == ":STOP[]"
        assert r.arm_stopped()
        # backing out of the violation is allowed: the lift rises without a new trip
        r.drv.set_gap(sim_cfg.touch_gap + 1e-3)
        assert r.drv.gap() == pytest.approx(sim_cfg.touch_gap + 1e-3, abs=1e-7)


def test_lowering_onto_the_sphere_beyond_the_overlap_limit_trips(rm: Any) -> None:
    sim_cfg = SimConfig(start_referenced=True, start_angle=0.8, lower_angle=0.8,
                        overlap_limit=0.5e-3)  # fmt: skip
    with rig(rm, sim_cfg) as r:
        with pytest.raises(InstrumentTrip) as err:
            r.drv.set_gap(sim_cfg.touch_gap - 0.7e-3)
        assert err.value.code == 31
        assert r.drv.gap() == pytest.approx(sim_cfg.touch_gap - 0.5e-3, abs=1.5e-6)
        assert not r.drv.status().gap_moving


def test_gap_below_the_configured_overlap_limit_is_refused_and_rotation_stops(rm: Any) -> None:
    config = RheometerConfig(touch_gap=3e-3, overlap_limit=1e-3)
    with rig(rm, config=config) as r:
        _spin(r)
        before = r.drv.gap()
        with pytest.raises(LimitError, match="overlap limit"):
            r.drv.set_gap(1.9e-3)
        assert r.sim.log[-1] == ":STOP[]"
        assert r.arm_stopped()
        assert r.drv.gap() == before
        r.drv.touch_gap = None  # before a contact search only gap_min applies
        r.drv.set_gap(1.9e-3, wait=False)


def test_bad_argument_is_a_device_error() -> None:
    from gelrig.drivers.mcr501.codec import decode_reply
    from gelrig.drivers.mcr501.commands import COMMANDS

    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True))
    reply = sim.handle(":GAP[99.0000]")
    with pytest.raises(DeviceErrorReply) as err:
        decode_reply(COMMANDS["set_gap"], reply[0])
    assert err.value.code == 13
    reply = sim.handle(":ROT[CW;fast]")
    with pytest.raises(DeviceErrorReply) as err:
        decode_reply(COMMANDS["rotate"], reply[0])
    assert err.value.code == 11
