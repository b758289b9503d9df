import numpy as np
import pytest

from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.events import (
    EventBus,
    Finished,
    InterlockTrip,
    RunState,
    Samples,
    StateChanged,
    StepFinished,
    StepStarted,
    as_columns,
)
from gelrig.protocols.recorder import Recorder


def test_bus_isolates_ordinary_subscribers_and_propagates_critical():
    bus = EventBus()
    seen = []

    def broken(event):
        raise RuntimeError("plot failed")

    bus.subscribe(broken)
    unsubscribe = bus.subscribe(seen.append)
    bus.publish(StateChanged(0.0, RunState.IDLE, RunState.RUNNING))
    assert len(seen) == 1
    unsubscribe()
    bus.publish(StateChanged(1.0, RunState.RUNNING, RunState.PAUSED))
    assert len(seen) == 1

    def disk_full(event):
        raise OSError("disk full")

    bus.subscribe(disk_full, critical=True)
    with pytest.raises(OSError):
        bus.publish(StateChanged(2.0, RunState.PAUSED, RunState.RUNNING))


def test_recorder_writes_the_story_of_a_run(tmp_path):
    run = RunDirectory.create(tmp_path / "r", {})
    bus = EventBus()
    bus.subscribe(Recorder(run), critical=True)
    bus.publish(StateChanged(0.0, RunState.IDLE, RunState.RUNNING))
    bus.publish(StepStarted(0.0, 0, "hold", "ramp_hold", {"hold_s": 10}, {"t_s": "s", "f_N": "N"}))
    for i in range(10):
        block = Samples(float(i), 0, as_columns(t_s=np.arange(10.0) + 10 * i, f_N=np.ones(10)))
        assert len(block) == 10
        bus.publish(block)
    bus.publish(InterlockTrip(9.5, "force", 3.0, 2.5, "N", "force over limit"))
    bus.publish(StepFinished(10.0, 0, "hold", "aborted", {"note": "trip"}))
    bus.publish(Finished(10.0, RunState.ABORTED, "interlock: force"))
    meta = run.read_metadata()
    assert meta["status"] == "aborted" and meta["reason"] == "interlock: force"
    assert meta["steps"][0]["samples"] == 100
    assert meta["interlock_trips"][0]["interlock"] == "force"
    assert run.read_step(0)["t_s"].size == 100
    assert run.completed_steps() == {}
