"""Run directories keep every flushed sample, even after SIGKILL."""

import json
import signal
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.store import RunDirectory, read_step, seal_step


def test_round_trip_and_metadata(tmp_path):
    run = RunDirectory.create(tmp_path / "r", {"protocol": {"name": "p"}})
    writer = run.open_step(0, "ramp & hold", "ramp_hold", {"t_s": "s", "force_N": "N"},
                           {"hold_s": 3000.0}, 0.0)
    for i in range(50):
        writer.append({"t_s": np.arange(100.0) + 100 * i, "force_N": np.full(100, 0.5)})
    writer.close("completed")
    run.finish_step(0, "completed", writer.rows, 12.0, {"first_touch_m": 1e-3})
    data = run.read_step(0)
    np.testing.assert_array_equal(data["t_s"], np.arange(5000.0))
    with h5py.File(writer.path, "r") as handle:  # closed normally: a plain open works
        assert handle["force_N"].attrs["unit"] == "N"
        assert json.loads(handle.attrs["params"]) == {"hold_s": 3000.0}
    meta = run.read_metadata()
    assert meta["steps"][0]["status"] == "completed"
    assert meta["steps"][0]["results"] == {"first_touch_m": 1e-3}
    assert run.completed_steps().keys() == {0}


def test_block_with_missing_column_is_refused(tmp_path):
    run = RunDirectory.create(tmp_path / "r", {})
    writer = run.open_step(0, "s", "k", {"a": "s", "b": "N"}, {}, 0.0)
    with pytest.raises(ValueError, match="every column"):
        writer.append({"a": np.ones(3)})
    writer.close()


def test_existing_run_and_missing_run(tmp_path):
    RunDirectory.create(tmp_path / "r", {})
    with pytest.raises(ConfigError, match="already holds a run"):
        RunDirectory.create(tmp_path / "r", {})
    with pytest.raises(ConfigError, match="not a run directory"):
        RunDirectory(tmp_path / "nothing").read_metadata()


WRITER = textwrap.dedent("""
    import sys, time
    import numpy as np
    import gelrig.instrument.core.store as store
    from gelrig.instrument.core.store import RunDirectory
    store.FLUSH_INTERVAL = 0.05
    run = RunDirectory.create(sys.argv[1], {"protocol": {}})
    w = run.open_step(0, "hold", "hold", {"t_s": "s", "force_N": "N"}, {}, 0.0)
    n = 0
    while True:
        w.append({"t_s": np.arange(n, n + 100, dtype=float), "force_N": np.ones(100)})
        n += 100
        if w.rows:
            print(w.rows, flush=True)
        time.sleep(0.002)
""")


def test_sigkill_mid_step_keeps_flushed_samples(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path / "r")],
                            stdout=subprocess.PIPE, text=True)
    flushed = 0
    deadline = time.monotonic() + 30
    while flushed < 5000 and time.monotonic() < deadline:
        flushed = int(proc.stdout.readline() or 0)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    proc.stdout.close()
    assert flushed >= 5000
    run = RunDirectory(tmp_path / "r")
    assert run.read_metadata()["steps"][0]["status"] == "running"
    data = run.read_step(0)
    assert data["t_s"].size >= flushed
    np.testing.assert_array_equal(data["t_s"], np.arange(data["t_s"].size, dtype=float))
    path = tmp_path / "r" / "steps" / "00_hold.h5"
    assert seal_step(path) is True
    with h5py.File(path, "r") as handle:  # sealed: a plain open works now
        assert handle["t_s"].shape[0] == data["t_s"].size
    assert seal_step(path) is False
    assert read_step(path)["force_N"].size == data["t_s"].size


RAGGED_WRITER = textwrap.dedent("""
    import os, sys
    import h5py, numpy as np
    handle = h5py.File(sys.argv[1], "w", libver="latest")
    handle.attrs["columns"] = '["t_s", "force_N"]'
    for name, n in (("t_s", 10), ("force_N", 7)):
        handle.create_dataset(name, data=np.arange(float(n)), maxshape=(None,), chunks=(4,))
    handle.swmr_mode = True
    handle.flush()
    os._exit(0)  # as a kill between two column flushes: the file stays open for writing
""")


def test_a_file_left_open_by_a_crash_keeps_only_complete_rows(tmp_path):
    """A kill between two column flushes leaves columns of unequal length: a row exists once
    every column has it, and sealing keeps those rows."""
    path = tmp_path / "ragged.h5"
    subprocess.run([sys.executable, "-c", RAGGED_WRITER, str(path)], check=True)
    with pytest.raises(OSError):
        h5py.File(path, "r")  # open for writing still, as a crash leaves it
    data = read_step(path)
    assert data["t_s"].size == data["force_N"].size == 7
    np.testing.assert_array_equal(data["t_s"], np.arange(7.0))
    assert seal_step(path) is True
    with h5py.File(path, "r") as handle:
        assert handle["t_s"].shape == handle["force_N"].shape == (7,)
        assert handle.attrs["sealed_after_crash"]


def test_a_closed_file_with_columns_of_unequal_length_is_refused(tmp_path):
    """A closed file is never ragged: cutting it to the shortest column would hide damage."""
    path = tmp_path / "ragged.h5"
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(["t_s", "force_N"])
        handle.create_dataset("t_s", data=np.arange(10.0))
        handle.create_dataset("force_N", data=np.ones(7))
    with pytest.raises(ConfigError, match=r'column t_s = "10 rows": column force_N has 7; '
                                          r"the columns of a closed step file have equal"):
        read_step(path)


#: A step closed when its file may not grow (RLIMIT_FSIZE at its size, as a disk that filled
#: during the step): the status is set in place, so the close needs no new space.
FULL_AT_CLOSE = textwrap.dedent("""
    import os, resource, signal, sys
    import numpy as np
    from gelrig.instrument.core.store import StepWriter
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    w = StepWriter(__import__("pathlib").Path(sys.argv[1]), {"t_s": "s", "force_N": "N"}, {})
    w.append({"t_s": np.arange(500.0), "force_N": np.ones(500)})
    w.flush()
    size = os.path.getsize(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    w.close("completed")
    print(w.dead or "closed", flush=True)
""")


def test_a_step_closed_on_a_full_disk_stays_readable(tmp_path):
    """The soak's finding (benchmarks/bench_chaos_soak.py, disk_full): reopening the closed
    file read-write to add the status failed on the full disk, the failed handle crashed the
    interpreter (exit -11) and left the file flagged open by a plain writer, which no reader
    (nor resume) could open: every sample of the step was lost."""
    path = tmp_path / "00_hold.h5"
    done = subprocess.run([sys.executable, "-c", FULL_AT_CLOSE, str(path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "closed"
    with h5py.File(path, "r") as handle:  # closed normally
        assert handle.attrs["status"] == b"completed"
    np.testing.assert_array_equal(read_step(path)["t_s"], np.arange(500.0))


def test_run_json_on_a_full_disk_is_never_left_cut_off(tmp_path, monkeypatch):
    """The chaos soak's disk_full: with no space and no reserve left, a run.json that grew
    cannot be rewritten in place (it would be cut off mid-way, invalid); the file keeps its
    last whole text and the write raises StorageFault. One that fits its blocks is written."""
    import errno
    import json

    from gelrig.instrument.core import store
    from gelrig.instrument.core.store import StorageFault

    path = tmp_path / "run.json"
    path.write_text(json.dumps({"status": "running", "steps": []}, indent=1))
    before = path.read_text()

    def no_space(*_args: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(store, "_write_replace", no_space)
    longer = json.dumps({"status": "failed", "steps": [], "reason": "disk full" * 50}, indent=1)
    with pytest.raises(StorageFault, match="disk full"):
        store._atomic_write_text(path, longer)
    assert path.read_text() == before and json.loads(path.read_text())["status"] == "running"
    shorter = json.dumps({"status": "failed", "steps": []})
    store._atomic_write_text(path, shorter)
    assert json.loads(path.read_text())["status"] == "failed"
    assert not (tmp_path / "run.json.tmp").exists()
