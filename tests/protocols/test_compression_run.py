"""The compression protocols end to end: runner -> KDC101 driver -> APT bytes over a pyserial
URL -> stage simulator, and USB-6001 driver -> official nidaqmx -> gRPC -> simulated DAQ."""

import copy
import threading
import tomllib

import numpy as np
import pytest

from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, InterlockTrip, RunState, Samples, StateChanged
from gelrig.protocols.recorder import Recorder
from gelrig.protocols.rig import CompressionLimits
from gelrig.protocols.runner import Runner
from gelrig.protocols.spec import paper_protocol, parse_protocol

TRUE_TOUCH = 6.2e-3  # protocols/rigs/compression.toml [simulator] first_touch
TRUE_G_E, TRUE_TAU = 7146.0, 1413.0


def paper_table(**hold_overrides):
    table = tomllib.loads(paper_protocol("compression").read_text())
    table = copy.deepcopy(table)
    table["step"][1].update(hold_overrides)
    return table


def record(rig, protocol, tmp_path, control=None, bus=None):
    run = RunDirectory.create(tmp_path / "run", {})
    bus = bus or EventBus()
    bus.subscribe(Recorder(run), critical=True)
    runner = Runner(rig, protocol, bus, control)
    return runner, run


@pytest.mark.parametrize("rate", ["1000 Hz", "100 Hz"])
def test_paper_compression_finds_touch_and_recovers_the_material(make_rig, tmp_path, rate):
    rig = make_rig("compression")
    runner, run = record(rig, parse_protocol(paper_table(rate=rate)), tmp_path)
    assert runner.run() is RunState.COMPLETED, runner.reason
    search, hold = runner.results[0], runner.results[1]
    assert search["first_touch_m"] == pytest.approx(TRUE_TOUCH, abs=10e-6)
    assert search["first_touch_spread_m"] < 10e-6
    fit = hold["fits"][0]
    assert fit["G_e"] == pytest.approx(TRUE_G_E, rel=0.02)
    assert fit["relax"][0]["tau"] == pytest.approx(TRUE_TAU, rel=0.02)
    data = run.read_step(1)
    expected = 3000 * float(rate.split()[0])
    assert data["t_s"].size > expected
    for recorded in (data, run.read_step(0)):  # tare samples included: no gaps, no repeats
        steps = np.diff(recorded["t_s"])
        assert np.allclose(steps, steps[0], rtol=1e-6)
    assert data["delta_m"].max() == pytest.approx(0.06 * 18.63e-3, abs=2e-6)


def short_protocol(hold="20 s", rate="100 Hz"):
    table = paper_table(hold=hold, rate=rate, terms=1)
    table["step"][0]["confirm"] = 0
    return parse_protocol(table)


def _start(runner):
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault("state", runner.run()))
    thread.start()
    return thread, result


def test_pause_and_resume(make_rig, tmp_path):
    rig = make_rig("compression")
    control = RunControl()
    bus = EventBus()
    paused = threading.Event()
    bus.subscribe(lambda e: paused.set() if isinstance(e, StateChanged)
                  and e.new is RunState.PAUSED else None)
    runner, _ = record(rig, short_protocol(), tmp_path, control, bus)
    control.pause()
    thread, result = _start(runner)
    assert paused.wait(30)
    assert not rig.stage.is_moving()
    control.resume()
    thread.join(60)
    assert result["state"] is RunState.COMPLETED


def test_abort_mid_ramp_stops_the_stage(make_rig, tmp_path):
    rig = make_rig("compression")
    control = RunControl()
    bus = EventBus()
    pressing = threading.Event()

    def watch(event):
        if isinstance(event, Samples) and event.index == 1 and np.any(event.data["delta_m"] > 0):
            pressing.set()
            control.abort("test abort")  # from the runner's own thread: at once

    bus.subscribe(watch)
    runner, run = record(rig, short_protocol(), tmp_path, control, bus)
    assert runner.run() is RunState.ABORTED
    assert pressing.is_set()
    assert not rig.stage.is_moving()
    position = rig.stage.position()
    rig.clock.sleep(5.0)
    assert rig.stage.position() == pytest.approx(position, abs=1e-7)  # it stays stopped
    meta = run.read_metadata()
    assert meta["status"] == "aborted" and meta["steps"][1]["status"] == "aborted"


def test_force_interlock_trips_within_one_sample(make_rig, tmp_path):
    rig = make_rig("compression")
    rig.limits = CompressionLimits(max_force=0.02)
    trips = []
    bus = EventBus()
    bus.subscribe(lambda e: trips.append(e) if isinstance(e, InterlockTrip) else None)
    runner, run = record(rig, short_protocol(), tmp_path, bus=bus)
    assert runner.run() is RunState.ABORTED
    assert "interlock force" in runner.reason
    data = run.read_step(1)
    force = data["force_N"]
    assert force[-1] > 0.02 and np.all(force[:-1] <= 0.02)
    assert trips[0].t - data["t_s"][-1] <= 0.01 + 1e-9  # seen within one sample (100 Hz)
    assert not rig.stage.is_moving()
    assert run.read_metadata()["interlock_trips"][0]["limit"] == 0.02
