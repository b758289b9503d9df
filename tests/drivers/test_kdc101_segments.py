"""Bounded stage motion (ADR 0201): the segment arithmetic, and the KDC101 driver's segments
against the simulated controller in virtual time."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gelrig.drivers.kdc101 import KDC101
from gelrig.drivers.kdc101.apt import MsgId
from gelrig.drivers.kdc101.payloads import unpack_position
from gelrig.drivers.kdc101.segments import SegmentPlan, rest_to_rest_time
from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import InstrumentError
from gelrig.simulators.kdc101 import KDC101Simulator, register, unregister

_names = itertools.count()


# ---- the arithmetic ------------------------------------------------------------------------

@given(speed=st.floats(1e-6, 2.6e-3), accel=st.floats(1e-4, 10e-3), bound=st.floats(0.5, 10))
def test_a_plan_keeps_the_profile_and_states_its_bound(speed: float, accel: float,
                                                       bound: float) -> None:
    plan = SegmentPlan.of(speed, accel, bound)
    brake = speed * speed / (2 * accel)
    # renewed every quarter bound, a quarter bound before the stage would start to slow down
    assert plan.renew_every == pytest.approx(bound / 4)
    assert plan.late_after >= bound / 2 - 1e-9
    assert plan.late_after == pytest.approx((plan.lookahead - brake) / speed)
    # from rest, a segment is a trapezoid that ends within stop_within (the bound, or more
    # only where stopping alone takes longer: v / a > bound / 3)
    assert plan.stop_within >= rest_to_rest_time(plan.lookahead, speed, accel) - 1e-9
    if speed / accel <= bound / 3:
        assert plan.stop_within == pytest.approx(bound)
    else:
        assert plan.stop_within == pytest.approx(bound / 2 + 1.5 * speed / accel)


def test_the_rig_defaults_stop_within_two_seconds() -> None:
    for speed in (0.0373e-3, 0.3e-3, 1e-3, 2.3e-3, 2.6e-3):  # ramp, probe, fast, caps
        plan = SegmentPlan.of(speed, 4e-3, 2.0)
        assert plan.stop_within == pytest.approx(2.0)
        assert plan.lookahead == pytest.approx(speed * (2.0 - speed / 4e-3))


def test_a_renewed_target_never_overshoots_the_final_one() -> None:
    from gelrig.drivers.kdc101.segments import BoundedMove

    plan = SegmentPlan.of(1e-3, 4e-3, 2.0)
    up = BoundedMove(10.0, 1, 1.75, plan, 0.0, 0.0)
    assert up.next_target(0.0) == 1.75
    assert up.next_target(8.25) == 10.0
    assert up.next_target(9.5) == 10.0
    down = BoundedMove(-3.0, -1, 1.75, plan, 0.0, 0.0)
    assert down.next_target(0.0) == -1.75
    assert down.next_target(-2.0) == -3.0
    assert not up.due(0.4) and up.due(0.5) and not up.late(1.5) and up.late(1.7)


# ---- the driver on the simulated controller ------------------------------------------------

@dataclass
class Rig:
    clock: VirtualClock
    sim: KDC101Simulator
    stage: KDC101

    def sent(self, msg_id: int) -> list[int]:
        """Positions of every message ``msg_id`` the controller received (data forms)."""
        return [unpack_position(m.data)[1] for m in self.sim.received
                if m.msg_id == msg_id and m.data is not None]

    def run_for(self, seconds: float) -> None:
        keep_moving(self.clock, self.stage, seconds, self.stage.config.motion_bound_s)


def _rig(bound: float = 2.0) -> Iterator[Rig]:
    clock = VirtualClock(100.0)
    sim = KDC101Simulator(clock)
    name = f"seg{next(_names)}"
    url = register(sim, name)
    stage = KDC101(url, StageConfig(max_position_m=20e-3, motion_bound_s=bound), clock).open()
    stage.home()
    try:
        yield Rig(clock, sim, stage)
    finally:
        stage.close()
        unregister(name)


@pytest.fixture
def rig() -> Iterator[Rig]:
    yield from _rig()


CPM = 34554.96e3


def test_a_short_move_is_one_command(rig: Rig) -> None:
    rig.stage.set_velocity(1e-3, 4e-3)
    rig.stage.move_to(1.5e-3)  # 1.75 s from rest: within the bound
    assert rig.sent(MsgId.MOT_MOVE_ABSOLUTE) == [round(1.5e-3 * CPM)]
    assert rig.stage.renewals == 0


def test_a_long_move_goes_out_as_renewed_segments_and_ends_exactly(rig: Rig) -> None:
    rig.stage.set_velocity(2.3e-3, 4e-3)
    rig.stage.move_to(15e-3)  # wait=True: the driver's own wait renews
    targets = rig.sent(MsgId.MOT_MOVE_ABSOLUTE)
    plan = SegmentPlan.of(2.3e-3, 4e-3, 2.0)
    assert len(targets) > 10 and targets[-1] == round(15e-3 * CPM)
    assert targets == sorted(targets)
    assert max(np.diff([0, *targets])) <= plan.lookahead * CPM + 2  # never more than L ahead
    assert rig.stage.position_counts() == round(15e-3 * CPM)
    assert not rig.stage.is_moving()


def test_renewals_leave_the_trajectory_of_one_command() -> None:
    """The same 8 mm move at 1 mm/s (8.25 s) sent whole (bound 10 s) and as renewed segments
    (bound 2 s): the twin's path is the same to rounding, so is every force computed from it."""
    paths = []
    for bound in (10.0, 2.0):
        for rig in _rig(bound):
            rig.stage.set_velocity(1e-3, 4e-3)
            start = rig.clock.now()
            rig.stage.move_to(8e-3, wait=False)
            rig.run_for(10.0)
            assert not rig.stage.is_moving()
            assert (rig.stage.renewals == 0) == (bound == 10.0)
            ts = np.linspace(start, rig.clock.now(), 5001)
            paths.append(rig.sim.positions_at(ts))
    whole, segmented = paths
    assert np.max(np.abs(whole - segmented)) < 1e-15  # metres
    assert segmented[-1] == whole[-1]


def test_a_velocity_move_is_never_sent_as_one(rig: Rig) -> None:
    rig.stage.set_velocity(1e-3, 4e-3)
    rig.stage.move_velocity(+1)
    rig.run_for(5.0)
    assert not [m for m in rig.sim.received if m.msg_id == MsgId.MOT_MOVE_VELOCITY]
    speed = rig.sim.velocity_at(rig.clock.now())
    assert abs(speed) == pytest.approx(1e-3, rel=1e-3)  # still cruising while renewed
    rig.stage.stop()
    assert not rig.stage.is_moving()


@pytest.mark.parametrize("speed", [0.3e-3, 1e-3, 2.3e-3])
def test_left_alone_the_stage_stops_within_the_bound(rig: Rig, speed: float) -> None:
    """gelrig stops talking (it died): the stage comes to rest within motion_bound of the
    last segment it sent, at most ``lookahead`` past where it was then."""
    rig.stage.set_velocity(speed, 4e-3)
    rig.stage.move_velocity(+1)
    rig.run_for(3.0)
    last = rig.stage._segment
    assert last is not None
    sent, where = last.renewed_at, rig.sim.position_at(last.renewed_at)
    rest = rig.sim.kinematics.end_time  # nothing renews it any more
    assert rest - sent <= 2.0 + 1e-9
    assert rig.sim.velocity_at(sent + 2.0) == 0.0
    travelled = rig.sim.position_at(sent + 5.0) - where
    assert 0 < travelled <= last.lookahead / CPM + 1e-9


def test_a_renewal_too_late_raises_and_stops(rig: Rig) -> None:
    rig.stage.set_velocity(2.3e-3, 4e-3)
    rig.stage.move_to(18e-3, wait=False)
    rig.clock.advance(1.3)  # later than late_after (1.14 s): the stage may be slowing
    with pytest.raises(InstrumentError, match=r"renewed 1\.30 s after the last"):
        rig.stage.position()
    assert rig.sim.received[-1].msg_id == MsgId.MOT_MOVE_STOP
    assert rig.stage._segment is None
    assert rig.stage.position() < 18e-3  # abandoned, not resumed


def test_a_stop_ends_the_renewals(rig: Rig) -> None:
    rig.stage.set_velocity(1e-3, 4e-3)
    rig.stage.move_to(15e-3, wait=False)
    rig.run_for(1.0)
    rig.stage.stop()
    n = len(rig.sent(MsgId.MOT_MOVE_ABSOLUTE))
    rig.run_for(5.0)
    rig.stage.position()
    assert len(rig.sent(MsgId.MOT_MOVE_ABSOLUTE)) == n  # nothing renewed after the stop
    assert not rig.stage.is_moving()
