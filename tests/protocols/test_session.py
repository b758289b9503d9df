"""RecordedRun: the one wiring of a recorded run (CLI and GUI), on the simulated rigs."""

import copy
import tomllib

import pytest

from instrument.errors import GelrigError
from instrument.store import RunDirectory
from protocols.control import RunControl
from protocols.events import EventBus, RunState
from protocols.session import RecordedRun
from protocols.spec import paper_protocol, parse_protocol


def short_compression():
    table = copy.deepcopy(tomllib.loads(paper_protocol("compression").read_text()))
    table["step"][0]["confirm"] = 0
    table["step"][1].update(hold="20 s", rate="100 Hz", terms=1)
    return parse_protocol(table)


def test_records_identities_status_and_every_step(make_rig, tmp_path):
    rig = make_rig("compression")
    bus, control = EventBus(), RunControl()
    seen = []
    bus.subscribe(seen.append)
    recorded = RecordedRun(rig, short_compression(), bus, control)
    assert recorded.bus is bus and recorded.control is control
    run = RunDirectory.create(tmp_path / "run", {})
    assert recorded.record(run) is recorded
    meta = run.read_metadata()
    assert meta["status"] == "running" and meta["instruments"] == rig.identities
    assert recorded.run() is RunState.COMPLETED, recorded.reason
    assert recorded.state is RunState.COMPLETED and recorded.reason == "all steps completed"
    meta = run.read_metadata()
    assert meta["status"] == "completed"
    assert [s["status"] for s in meta["steps"]] == ["completed", "completed"]
    assert run.read_step(1)["t_s"].size > 20 * 100
    assert seen  # other subscribers of the same bus see the run too


def test_a_protocol_for_the_other_rig_is_refused_before_anything_is_written(make_rig):
    with pytest.raises(GelrigError, match="compression rig"):
        RecordedRun(make_rig("shear"), short_compression())


def test_a_run_is_never_unrecorded(make_rig, tmp_path):
    recorded = RecordedRun(make_rig("compression"), short_compression())
    with pytest.raises(GelrigError, match="record"):
        recorded.run()
    recorded.record(RunDirectory.create(tmp_path / "a", {}))
    with pytest.raises(GelrigError, match="already records"):
        recorded.record(RunDirectory.create(tmp_path / "b", {}))


def test_a_recorder_that_cannot_write_stops_the_run(make_rig, tmp_path, monkeypatch):
    rig = make_rig("compression")
    run = RunDirectory.create(tmp_path / "run", {})

    def disk_full(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(run, "open_step", disk_full)
    recorded = RecordedRun(rig, short_compression()).record(run)
    # an unexpected error ends the run like an instrument's: stopped, recorded, not raised
    assert recorded.run() is RunState.FAILED
    assert recorded.reason.startswith("OSError: disk full")
    assert run.read_metadata()["status"] == "failed"
