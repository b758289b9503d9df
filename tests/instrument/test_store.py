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

from instrument.errors import ConfigError
from instrument.store import RunDirectory, read_step, seal_step


def test_round_trip_and_metadata(tmp_path):
    run = RunDirectory.create(tmp_path / "r", {"protocol": {"name": "p"}})
    writer = run.open_step(0, "ramp & hold", "ramp_hold", {"t_s": "s", "force_N": "N"},
                           {"hold_s": 3000.0}, 0.0)
    for i in range(50):
        writer.append({"t_s": np.arange(100.0) + 100 * i, "force_N": np.full(100, 0.5)})
    writer.close({"status": "completed"})
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
    import instrument.store as store
    from instrument.store import RunDirectory
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


def test_read_step_keeps_only_complete_rows(tmp_path):
    """A kill between two column flushes leaves columns of unequal length."""
    path = tmp_path / "ragged.h5"
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(["t_s", "force_N"])
        handle.create_dataset("t_s", data=np.arange(10.0))
        handle.create_dataset("force_N", data=np.ones(7))
    data = read_step(path)
    assert data["t_s"].size == data["force_N"].size == 7
    np.testing.assert_array_equal(data["t_s"], np.arange(7.0))
