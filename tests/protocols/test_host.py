"""RunHost: the one host of a recorded run (CLI, API, GUI, demo, campaign), on the simulated
rigs."""

import contextlib
import copy
import logging
import os
import signal
import threading
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

import pytest

from gelrig.instrument.core.errors import ConfigError, GelrigError
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, RunState
from gelrig.protocols.host import LOG_NAME, RunHost, run_logging
from gelrig.protocols.spec import paper_protocol, parse_protocol


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
    run = RunDirectory.create(tmp_path / "run", {})
    host = RunHost(rig, short_compression(), run, bus=bus, control=control)
    assert host.bus is bus and host.control is control
    with host:
        meta = run.read_metadata()
        assert meta["status"] == "running" and meta["instruments"] == rig.identities
        assert host.run() is RunState.COMPLETED, host.reason
    assert host.state is RunState.COMPLETED and host.reason == "all steps completed"
    meta = run.read_metadata()
    assert meta["status"] == "completed"
    assert [s["status"] for s in meta["steps"]] == ["completed", "completed"]
    assert run.read_step(1)["t_s"].size > 20 * 100
    assert seen  # other subscribers of the same bus see the run too
    assert (run.path / LOG_NAME).is_file()  # the run's own log


def test_a_protocol_for_the_other_rig_is_refused_before_anything_is_written(make_rig,
                                                                            tmp_path):
    run = RunDirectory.create(tmp_path / "run", {})
    with pytest.raises(GelrigError, match="compression rig"):
        RunHost(make_rig("shear"), short_compression(), run)
    assert run.read_metadata()["status"] == "created"


def test_a_run_is_hosted_inside_its_with_block_and_holds_its_lock(make_rig, tmp_path):
    run = RunDirectory.create(tmp_path / "a", {})
    host = RunHost(make_rig("compression"), short_compression(), run)
    with pytest.raises(GelrigError, match="with block"):
        host.run()
    with host, pytest.raises(ConfigError, match="in use"), run.lock():
        pass  # a second holder (another resume) is refused while the run is hosted
    with run.lock():  # released on the way out
        pass


def test_on_its_worker_thread_the_host_reports_the_outcome(make_rig, tmp_path):
    run = RunDirectory.create(tmp_path / "run", {})
    with RunHost(make_rig("compression"), short_compression(), run) as host:
        host.start()
        while not host.wait(0.1):
            pass
    assert host.outcome() is RunState.COMPLETED and not host.stuck()


def test_a_recorder_that_cannot_write_stops_the_run(make_rig, tmp_path, monkeypatch):
    rig = make_rig("compression")
    run = RunDirectory.create(tmp_path / "run", {})

    def disk_full(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(run, "open_step", disk_full)
    with RunHost(rig, short_compression(), run) as host:
        # an unexpected error ends the run like an instrument's: stopped, recorded, not raised
        assert host.run() is RunState.FAILED
    assert host.reason.startswith("OSError: disk full")
    assert run.read_metadata()["status"] == "failed"


def test_a_resume_continues_the_runs_time_base(make_rig, tmp_path):
    from gelrig.instrument.core.clock import PacedClock, VirtualClock
    from gelrig.protocols.host import last_lab_time, prepare_resume

    run = RunDirectory.create(tmp_path / "run", {})
    with RunHost(make_rig("compression"), short_compression(), run) as host:
        assert host.run() is RunState.COMPLETED
    meta = run.read_metadata()
    end = last_lab_time(meta)
    assert end == max(s["finished"] for s in meta["steps"]) > 20.0
    clock = VirtualClock()
    prepare_resume(run, meta, "virtual", clock)
    assert clock.now() == end  # not 0: the analysis joins the steps in time order
    paced = PacedClock(1.0)
    prepare_resume(run, meta, "paced:1", paced)
    assert end <= paced.now() < end + 1.0
    later = VirtualClock(end + 50.0)
    prepare_resume(run, meta, "virtual", later)
    assert later.now() == end + 50.0  # never moved back


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_log_file_on_a_full_disk_ends_quietly(capfd):
    """Every write to /dev/full fails with ENOSPC, as gelrig.log on a disk that filled during
    the run (the chaos soak's disk_full): no "Logging error" traceback on the terminal, and
    the log's close raises nothing."""
    with run_logging(Path("/dev/full")):
        for i in range(3):
            logging.getLogger("gelrig").error("run failed: %s", i)
    err = capfd.readouterr().err
    assert "Logging error" not in err and "Traceback" not in err, err


class _NeverConfirmed:
    """A rig whose safe stop takes 0.4 s, swallows every error (KeyboardInterrupt included,
    as the real one does) and never confirms."""

    def __init__(self) -> None:
        self.attempts = 0
        self.started = threading.Event()

    def safe_stop(self, reason: str, budget: float) -> SimpleNamespace:
        self.attempts += 1
        self.started.set()
        with contextlib.suppress(BaseException):  # what the safe stop does
            time.sleep(0.4)
        return SimpleNamespace(verified=False)


@pytest.mark.skipif(not hasattr(signal, "pthread_kill"), reason="needs pthread_kill")
def test_ctrl_c_during_a_pending_safe_stop_attempt_gives_up(monkeypatch):
    """A Ctrl-C that lands inside a retry of a pending safe stop (the chaos soak's shear
    link_frozen: it was swallowed there and the retries ran their full 60 s) gives up once
    that attempt returns."""
    rig = _NeverConfirmed()
    host = SimpleNamespace(pending=SimpleNamespace(reason="frozen"), rig=rig,
                           pending_given_up=False)
    main = threading.get_ident()
    timer = threading.Thread(target=lambda: rig.started.wait(5) and (
        time.sleep(0.1), signal.pthread_kill(main, signal.SIGINT)))
    timer.start()
    safe = RunHost.complete_pending(host, period=0.05, limit=5.0)  # type: ignore[arg-type]
    timer.join(5)
    assert safe is None
    assert host.pending_given_up is True
    assert rig.attempts == 1
