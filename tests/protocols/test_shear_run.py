"""The shear protocols end to end: runner -> MCR 501 driver -> pyvisa-py TCP -> simulator."""

import threading

import numpy as np
import pytest

from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, InterlockTrip, RunState, Samples, StateChanged
from gelrig.protocols.recorder import Recorder
from gelrig.protocols.rig import ShearLimits
from gelrig.protocols.runner import Runner
from gelrig.protocols.spec import load_protocol, paper_protocol, parse_protocol


def short_ladder(**params):
    step = {"kind": "speed_ladder", "overlaps": 1, "first_overlap": "0.6 mm",
            "speeds": ["1.19e-4 m/s", "2.37e-4 m/s"], "travel": "14 mm", "wait": "5 s",
            "touch_gap": "3 mm", "centre_angle": 0.8, **params}
    return parse_protocol({"protocol": {"name": "short", "rig": "shear"}, "step": [step]})


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    """The paper's shear protocol on the built-in simulated rig (TCP), recorded."""
    from gelrig.factory import build_rig
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.protocols.rigfile import default_rig, load_rig

    rig = build_rig(load_rig(default_rig("shear")), VirtualClock())
    run = RunDirectory.create(tmp_path_factory.mktemp("shear") / "run", {})
    bus = EventBus()
    bus.subscribe(Recorder(run), critical=True)
    runner = Runner(rig, load_protocol(paper_protocol("shear")), bus)
    try:
        state = runner.run()
    finally:
        rig.close()
    return state, runner, run


def test_paper_shear_protocol_completes_and_finds_the_contact(paper_run):
    state, runner, _ = paper_run
    assert state is RunState.COMPLETED, runner.reason
    search = runner.results[0]
    # hidden truth of protocols/rigs/shear.toml: touch gap 3 mm, lower sphere at 0.8 rad
    assert search["touch_gap_m"] == pytest.approx(3e-3, abs=0.1e-3)
    assert search["touch_gap_m"] == pytest.approx(3e-3, abs=0.03e-3)
    assert search["lower_sphere_angle_rad"] == pytest.approx(0.8, abs=0.01)
    # the threshold fires below the touch gap, on the 0.1 mm grid from the safe gap
    depth = 3e-3 - search["contact_gap_m"]
    assert 0.3e-3 < depth < 1.0e-3
    assert round((4e-3 - search["contact_gap_m"]) / 1e-4, 6) % 1 == 0


def test_paper_ladder_yields_every_pass(paper_run):
    _, _, run = paper_run
    data = run.read_step(1)
    passes = data["pass"][data["pass"] >= 0]
    assert sorted(set(passes.astype(int))) == list(range(40))
    combos = {(round(o * 1e5), s, d) for o, s, d in
              zip(data["overlap_m"][data["pass"] >= 0], data["speed_m_s"][data["pass"] >= 0],
                  data["direction"][data["pass"] >= 0])}
    assert len(combos) == 5 * 4 * 2
    # every recorded pass touched: torque rose well above the noise
    for k in (0, 17, 39):
        torque = np.abs(data["torque_Nm"][data["pass"] == k])
        assert torque.max() > 50e-6
    meta = run.read_metadata()
    assert [s["status"] for s in meta["steps"]] == ["completed", "completed"]


def _start(runner):
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault("state", runner.run()))
    thread.start()
    return thread, result


def test_pause_at_checkpoint_and_resume(make_rig):
    rig = make_rig("shear")
    control = RunControl()
    bus = EventBus()
    states = []
    paused = threading.Event()

    def watch(event):
        if isinstance(event, StateChanged):
            states.append(event.new)
            if event.new is RunState.PAUSED:
                paused.set()

    bus.subscribe(watch)
    control.pause()  # takes effect at the first checkpoint
    thread, result = _start(Runner(rig, short_ladder(), bus, control))
    assert paused.wait(30)
    assert not rig.rheometer.status().busy  # nothing moves while paused
    control.resume()
    thread.join(60)
    assert result["state"] is RunState.COMPLETED
    assert states[:3] == [RunState.RUNNING, RunState.PAUSED, RunState.RUNNING]


def test_abort_mid_pass_stops_rotation(make_rig):
    rig = make_rig("shear")
    control = RunControl()
    bus = EventBus()
    turning = threading.Event()

    def watch(event):
        if isinstance(event, Samples) and np.any(event.data["pass"] >= 0):
            turning.set()

    bus.subscribe(watch)
    thread, result = _start(Runner(rig, short_ladder(), bus, control))
    assert turning.wait(30)
    control.abort("test abort")
    thread.join(30)
    assert result["state"] is RunState.ABORTED
    rig.clock.sleep(5.0)  # the motor ramps down
    status = rig.rheometer.status()
    assert status.mode != "rotating" and not status.accelerating


def test_interlock_trip_stops_within_one_sample(make_rig, tmp_path):
    rig = make_rig("shear")
    rig.limits = ShearLimits(max_torque=0.1e-3)
    run = RunDirectory.create(tmp_path / "run", {})
    bus = EventBus()
    bus.subscribe(Recorder(run), critical=True)
    trips = []
    bus.subscribe(lambda e: trips.append(e) if isinstance(e, InterlockTrip) else None)
    runner = Runner(rig, short_ladder(interval="0.1 s"), bus)
    assert runner.run() is RunState.ABORTED
    assert "interlock torque" in runner.reason
    data = run.read_step(0)
    torque = np.abs(data["torque_Nm"])
    assert torque[-1] > 0.1e-3 and np.all(torque[:-1] <= 0.1e-3)  # the trip is the last sample
    assert trips[0].t - data["t_s"][-1] <= 0.1 + 1e-9  # seen within one sample period
    rig.clock.sleep(5.0)
    assert rig.rheometer.status().mode != "rotating"
    meta = run.read_metadata()
    assert meta["status"] == "aborted" and meta["interlock_trips"][0]["interlock"] == "torque"
