import numpy as np
import pytest

from gelrig.instrument.core.motion import Phase, Trajectory, plan_move
from gelrig.instrument.core.stage_path import StagePath

V, A = 1e-3, 4e-3  # m/s, m/s^2


def truth() -> Trajectory:
    """At 1 mm from 0 s; a move to 3 mm commanded at 10.0 s; at rest after 12.25 s."""
    traj = Trajectory(1e-3, 0.0)
    traj.replace_from(10.0, plan_move(10.0, 1e-3, 0.0, 3e-3, V, A))
    return traj


def test_positions_between_far_apart_reports_follow_the_commanded_move() -> None:
    true = truth()
    path = StagePath()
    path.reported(9.0, 9.001, 1e-3)
    path.commanded(9.9995, 10.0005, 3e-3, V, A)  # the write's window holds the true start
    path.reported(20.0, 20.001, 3e-3)  # the next report comes long after the stop
    ts = np.linspace(9.0, 20.0, 2001)
    z, flag = path.positions(ts)
    assert np.max(np.abs(z - true.positions_at(ts))) < 1e-6  # within 0.5 ms x 1 mm/s
    # a straight line between the two reports is 0.8 mm off in the middle of the move
    line = np.interp(ts, [9.0005, 20.0005], [1e-3, 3e-3])
    assert np.max(np.abs(line - true.positions_at(ts))) > 5e-4
    # the reports were more than max_gap apart while it moved: flagged, not trusted
    moving = (ts > 10.0) & (ts < 12.25)
    assert flag[moving].all() and not flag[(ts > 9.001) & (ts < 9.99)].any()


def test_reports_while_moving_pin_the_start_and_clear_the_flags() -> None:
    true = truth()
    path = StagePath()
    path.reported(9.0, 9.001, 1e-3)
    path.commanded(9.99, 10.01, 3e-3, V, A)  # a slow write: 10 ms wide
    for t in np.arange(10.1, 13.0, 0.1):  # polls every 0.1 s, 1 ms windows
        x = true.position_at(t + 0.0004)
        path.reported(t, t + 0.001, round(x / 2.9e-8) * 2.9e-8)  # encoder counts
    ts = np.linspace(10.0, 13.0, 601)
    z, flag = path.positions(ts)
    assert np.max(np.abs(z - true.positions_at(ts))) < 1e-6
    assert not flag.any()


def test_an_immediate_stop_is_placed_by_where_the_stage_stopped() -> None:
    true = truth()
    true.replace_from(11.0, [Phase(11.0, true.position_at(11.0), 0.0, 0.0)])
    path = StagePath()
    path.reported(9.0, 9.001, 1e-3)
    path.commanded(9.9999, 10.0001, 3e-3, V, A)
    path.stopped(10.995, 11.004, immediate=True)  # the stop's write: 9 ms wide
    path.reported(11.5, 11.501, true.position_at(11.5))
    ts = np.linspace(10.9, 11.2, 301)
    z, flag = path.positions(ts)
    assert np.max(np.abs(z - true.positions_at(ts))) < 2e-7
    assert not flag[ts > 11.0].any()


def test_a_report_that_disagrees_flags_its_span() -> None:
    path = StagePath()
    path.reported(0.0, 0.001, 1e-3)
    path.reported(1.0, 1.001, 1e-3)
    path.reported(2.0, 2.001, 1.5e-3)  # moved with no command the path knows of
    z, flag = path.positions(np.array([0.5, 1.5, 2.5]))
    assert list(flag) == [False, True, False]
    assert path.disagreements == 1
    assert z[2] == pytest.approx(1.5e-3)  # anchored again on the report


def test_a_move_that_started_outside_its_window_is_placed_by_the_report() -> None:
    true = truth()  # started at 10.0 s
    path = StagePath()
    path.reported(9.0, 9.001, 1e-3)
    path.commanded(9.95, 9.951, 3e-3, V, A)  # the window says 50 ms too early
    for t in np.arange(10.5, 12.6, 0.1):
        path.reported(t, t + 0.0005, true.position_at(t + 0.00025))
    ts = np.linspace(10.6, 12.6, 401)
    z, flag = path.positions(ts)
    assert path.disagreements == 1  # the first report; the move goes on from there
    assert np.max(np.abs(z - true.positions_at(ts))) < 1e-6
    assert not flag.any()
