"""Crafted and damaged run directories: export and analyze end with exit 2 and one line."""

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.store import RunDirectory, check_metadata, check_step_file, read_step
from tests.samples import SHORT_COMPRESSION

SHORT = SHORT_COMPRESSION.replace("{hold}", "60 s")
HOLD = "steps/01_ramp_and_hold.h5"


@pytest.fixture(scope="module")
def good_run(tmp_path_factory):
    """One completed short compression run, recorded once for the module."""
    from gelrig.cli import main

    base = tmp_path_factory.mktemp("good")
    (base / "short.toml").write_text(SHORT)
    assert main(["run", str(base / "short.toml"), "--out", str(base / "run")]) == 0
    return base / "run"


@pytest.fixture
def run_copy(good_run, tmp_path):
    target = tmp_path / "run"
    shutil.copytree(good_run, target)
    return target


def gelrig(*args, timeout=90):
    """The CLI in a subprocess, so that a hang fails the test instead of stalling it."""
    proc = subprocess.run([sys.executable, "-m", "gelrig.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)
    return proc.returncode, proc.stdout, proc.stderr


#: Runs a command and writes its peak resident memory (kB) to a file. The command is the child
#: of this small interpreter: a child's peak counts the memory it had before its exec, which
#: for a child of the test session would be the session's (hundreds of MB after other tests).
_PEAK = ("import resource, subprocess, sys; code = subprocess.run(sys.argv[2:]).returncode; "
         "open(sys.argv[1], 'w').write(str(resource.getrusage(resource.RUSAGE_CHILDREN)"
         ".ru_maxrss)); sys.exit(code)")


def gelrig_peak(*args, timeout=90):
    """:func:`gelrig`, with that process's own peak resident memory (kB)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        peak = Path(tmp) / "peak"
        proc = subprocess.run([sys.executable, "-c", _PEAK, str(peak), sys.executable, "-m",
                               "gelrig.cli", *map(str, args)], capture_output=True, text=True,
                              timeout=timeout, stdin=subprocess.DEVNULL)
        return proc.returncode, proc.stdout, proc.stderr, int(peak.read_text())


def edit_meta(run, change):
    meta = json.loads((run / "run.json").read_text())
    meta = change(meta)
    (run / "run.json").write_text(json.dumps(meta))


def _set_step(key, value):
    def change(meta):
        meta["steps"][1][key] = value
        return meta
    return change


def _replace_hold(make):
    def craft(run):
        path = run / HOLD
        path.unlink()
        make(path, run)
    return craft


def _truncate(run):
    path = run / HOLD
    os.truncate(path, path.stat().st_size // 2)


def _huge_dims(path, run):
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(["t_s", "force_N"])
        for name in ("t_s", "force_N"):
            handle.create_dataset(name, shape=(2**40,), maxshape=(None,), chunks=(1024,),
                                  dtype="f8")


def _strings(path, run):
    with h5py.File(path, "w") as handle:
        handle.create_dataset("t_s", data=np.array([b"a", b"b"]))


def _column_file(path, make, names=("t_s", "force_N")):
    """A closed step file whose columns ``make(handle, name)`` creates."""
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(list(names))
        for name in names:
            make(handle, name)


def _external_storage(path, run):
    """Each column's raw data 'stored' in /etc/passwd (was: exported into the CSV, exit 0)."""
    _column_file(path, lambda h, n: h.create_dataset(n, shape=(64,), dtype="f8",
                                                     external=[("/etc/passwd", 0, 512)]))


def _virtual(path, run):
    source = run / "steps" / "source.h5"
    with h5py.File(source, "w") as handle:
        handle.create_dataset("x", data=np.arange(100.0))

    def make(handle, name):
        layout = h5py.VirtualLayout(shape=(100,), dtype="f8")
        layout[:] = h5py.VirtualSource(str(source), "x", shape=(100,))
        handle.create_virtual_dataset(name, layout)
    _column_file(path, make)


def _soft_link(path, run):
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(["t_s", "force_N"])
        handle.create_dataset("t_s", data=np.arange(100.0))
        handle["force_N"] = h5py.SoftLink("/t_s")


def _external_link(path, run):
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(["t_s", "force_N"])
        handle.create_dataset("t_s", data=np.arange(100.0))
        handle["force_N"] = h5py.ExternalLink("/dev/zero", "/x")


def _unequal(path, run):
    with h5py.File(path, "w") as handle:
        handle.attrs["columns"] = json.dumps(["t_s", "force_N"])
        handle.create_dataset("t_s", data=np.arange(100.0))
        handle.create_dataset("force_N", data=np.ones(60))


def compressed_zeros(path, rows, chunk=1 << 17, chunks_written=None, names=("t_s", "force_N")):
    """Columns of ``rows`` zeros compressed about 1000x, written chunk by chunk as deflated
    bytes (HDF5's direct chunk write): a few MB of file declaring GB of columns."""
    import zlib

    packed = zlib.compress(bytes(chunk * 8), 9)
    count = -(-rows // chunk) if chunks_written is None else chunks_written

    def make(handle, name):
        ds = handle.create_dataset(name, shape=(rows,), dtype="f8", chunks=(chunk,),
                                   compression="gzip")
        for k in range(count):
            ds.id.write_direct_chunk((k * chunk,), packed)
    _column_file(path, make, names)


def _sparse_compressed(path, run):
    """2^29 rows a column declared, one chunk stored: 4 GiB from 1 kB."""
    compressed_zeros(path, 2**29, chunks_written=1)


def _huge_chunks(path, run):
    _column_file(path, lambda h, n: h.create_dataset(n, shape=(2**24,), dtype="f8",
                                                     chunks=(2**24,), compression="gzip"))


def _deep(run):
    (run / "run.json").write_text("[" * 100_000 + "]" * 100_000)


CRAFTED = {
    "run.json a list": (lambda run: (run / "run.json").write_text("[1, 2]"),
                        'run.json = "a list": must be a JSON object'),
    "steps missing": (lambda run: edit_meta(run, lambda m: {k: v for k, v in m.items()
                                                            if k != "steps"}),
                      'steps = "missing"'),
    "index a string": (lambda run: edit_meta(run, _set_step("index", "1")),
                       'steps[1].index = "1": must be an integer'),
    "samples a string": (lambda run: edit_meta(run, _set_step("samples", "many")),
                         'steps[1].samples = "many"'),
    "absolute path": (lambda run: edit_meta(run, _set_step("file", "/etc/passwd")),
                      'step 1 file = "/etc/passwd": must be a relative path'),
    "dot-dot path": (lambda run: edit_meta(run, _set_step("file", "../../etc/passwd")),
                     "must be a relative path inside the run directory"),
    "symlink to /dev/zero": (_replace_hold(lambda p, run: p.symlink_to("/dev/zero")),
                             "leads outside the run directory (to /dev/zero)"),
    "FIFO": (_replace_hold(lambda p, run: os.mkfifo(p)), "is a FIFO"),
    "not HDF5": (_replace_hold(lambda p, run: p.write_text("t_s,force_N\n1,2\n" * 100)),
                 "is not an HDF5 file"),
    "cut to half": (_truncate, "is truncated"),
    "dims of 2^40": (_replace_hold(_huge_dims), "1,099,511,627,776 rows"),
    "string column": (_replace_hold(_strings), "a step column is a 1-D array of numbers"),
    "external raw storage": (_replace_hold(_external_storage),
                             'column t_s = "/etc/passwd": is external raw storage'),
    "virtual dataset": (_replace_hold(_virtual), 'column t_s = "virtual dataset": reads its '
                        "data from other files"),
    "soft link": (_replace_hold(_soft_link), 'column force_N = "/t_s": is a soft link'),
    "external link": (_replace_hold(_external_link),
                      'column force_N = "/dev/zero:/x": is an external link'),
    "columns of unequal length": (_replace_hold(_unequal), 'column t_s = "100 rows": column '
                                  "force_N has 60; the columns of a closed step file have "
                                  "equal lengths"),
    "compressed, 4 GiB from 1 kB": (_replace_hold(_sparse_compressed),
                                    "a column expands at most 1100x"),
    "chunks of 128 MiB": (_replace_hold(_huge_chunks), 'column t_s = "chunks of 134,217,728 '
                          'bytes": at most 16,777,216'),
    "run.json a FIFO": (lambda run: ((run / "run.json").unlink(), os.mkfifo(run / "run.json")),
                        "run.json = ",),
    "run.json deeply nested": (_deep, "nested too deeply"),
    "run.json not UTF-8": (lambda run: (run / "run.json").write_bytes(
        '{"steps": []}'.encode("utf-16")), "is not UTF-8 text"),
}


ANALYZED = ["run.json a list", "index a string", "absolute path", "symlink to /dev/zero",
            "FIFO", "not HDF5", "cut to half", "dims of 2^40", "external raw storage",
            "virtual dataset", "soft link", "external link", "columns of unequal length",
            "compressed, 4 GiB from 1 kB"]


@pytest.mark.parametrize("command,case", [("export", c) for c in CRAFTED]
                         + [("analyze", c) for c in ANALYZED])
def test_crafted_run_directory_is_one_line_and_exit_2(run_copy, case, command):
    craft, expected = CRAFTED[case][0], CRAFTED[case][-1]
    craft(run_copy)
    args = [run_copy, "--csv"] if command == "export" else [run_copy]
    code, out, err = gelrig(command, *args)
    lines = err.strip().splitlines()
    assert code == 2, (out, err)
    assert len(lines) == 1 and "Traceback" not in out + err, err
    assert lines[0].startswith("gelrig: error: ") and expected in lines[0], lines[0]


def test_fifo_run_json_names_it(run_copy):
    (run_copy / "run.json").unlink()
    os.mkfifo(run_copy / "run.json")
    with pytest.raises(ConfigError, match="is a FIFO, not a file"):
        RunDirectory(run_copy).read_metadata()


def test_export_keeps_the_good_steps_before_naming_the_damaged_one(run_copy):
    _truncate(run_copy)
    code, _, err = gelrig("export", run_copy, "--csv")
    assert code == 2 and "01_ramp_and_hold.h5" in err and "is truncated" in err
    assert (run_copy / "csv" / "00_contact_search.csv").stat().st_size > 1000


def test_checks_accept_the_good_run_and_its_crash_files(good_run, tmp_path):
    run = RunDirectory(good_run)
    meta = run.read_metadata()
    assert check_metadata(meta) is meta
    for step in meta["steps"]:
        path = run.step_file(step)
        assert check_step_file(path) == path.stat().st_size
        assert read_step(path)["t_s"].size == step["samples"]


def test_symlink_inside_the_run_directory_is_followed(run_copy):
    target = run_copy / "steps" / "copy.h5"
    shutil.copyfile(run_copy / HOLD, target)
    (run_copy / HOLD).unlink()
    (run_copy / HOLD).symlink_to(target)
    assert RunDirectory(run_copy).read_step(1)["t_s"].size > 6000


def test_read_deadline(run_copy):
    with pytest.raises(ConfigError, match="could not be read within -1 s"):
        read_step(run_copy / HOLD, deadline=-1.0)


def test_a_dataset_bigger_than_its_file_is_refused_in_process(tmp_path):
    path = tmp_path / "big.h5"
    _huge_dims(path, tmp_path)
    with pytest.raises(ConfigError, match=r"1,099,511,627,776 rows.*at most 1,000,000,000"):
        read_step(path)
    with h5py.File(path, "w") as handle:  # within the rows bound, beyond the file
        handle.create_dataset("t_s", shape=(2**26,), chunks=(1024,), dtype="f8")
    with pytest.raises(ConfigError, match=r"declares 536,870,912 bytes of float64 in a file"):
        read_step(path)


def test_run_json_schema_messages():
    with pytest.raises(ConfigError, match=r"steps\[0\].file = \"missing\""):
        check_metadata({"steps": [{"index": 0, "name": "a", "kind": "k", "status": "s"}]})
    with pytest.raises(ConfigError, match=r"steps\[0\].index = true"):
        check_metadata({"steps": [{"index": True, "name": "a", "kind": "k", "status": "s",
                                   "file": "f"}]})
    with pytest.raises(ConfigError, match=r"status = 3: must be a string"):
        check_metadata({"steps": [], "status": 3})
    assert check_metadata({"steps": []}) == {"steps": []}


def test_step_file_names_are_kept_inside(tmp_path):
    run = RunDirectory.create(tmp_path / "r", {})
    assert run.step_file({"index": 0, "file": "steps/a.h5"}) == run.path / "steps/a.h5"
    (run.path / "steps" / "out").symlink_to(Path("/tmp"))
    with pytest.raises(ConfigError, match="leads outside"):
        run.step_file({"index": 0, "file": "steps/out/x.h5"})


def _declared_gib(run_copy, rows=2**28):
    """The hold replaced by a few MB of deflated zeros declaring 2 x ``rows`` floats (about
    1000x: within what deflate gives, so only the bounds on what is read can refuse it)."""
    path = run_copy / HOLD
    path.unlink()
    compressed_zeros(path, rows)
    return path


def test_a_few_mb_file_declaring_4_gib_is_refused_by_analyze_before_allocating(run_copy):
    """Was: analyze grew to 13-15 GB on a 7.85 MB step file."""
    path = _declared_gib(run_copy)
    assert path.stat().st_size < 8e6
    code, out, err, peak = gelrig_peak("analyze", run_copy)
    assert code == 2, (out, err)
    line = err.strip()
    assert "\n" not in line and "Traceback" not in out + err
    assert "holds 268,435,456 rows x 2 columns (4.0 GiB as floats); at most 2 GiB are read " \
           "whole (gelrig export streams any size)" in line
    assert peak < 600 * 1024  # kB: nothing of the 4 GiB was allocated


def test_export_streams_a_large_column_in_bounded_memory(run_copy):
    """Export reads and writes a chunk at a time: after seconds of streaming 2 x 2 GiB of
    columns its resident memory is a few hundred MB at most; Ctrl-C leaves no partial CSV."""
    import signal

    _declared_gib(run_copy)
    proc = subprocess.Popen([sys.executable, "-m", "gelrig.cli", "export", str(run_copy),
                             "--csv"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, stdin=subprocess.DEVNULL)
    part = run_copy / "csv" / "01_ramp_and_hold.csv.part"
    try:
        deadline = time.monotonic() + 60
        while not (part.exists() and part.stat().st_size > 20e6):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "export wrote nothing in time"
            time.sleep(0.1)
        status = Path(f"/proc/{proc.pid}/status").read_text()
        peak_kb = int(next(line.split()[1] for line in status.splitlines()
                           if line.startswith("VmHWM:")))
    finally:
        proc.send_signal(signal.SIGINT)
        _out, err = proc.communicate(timeout=60)
    assert peak_kb < 400 * 1024, peak_kb  # whole columns would be 4 GiB
    assert proc.returncode == 130, err
    assert not part.exists()
    assert (run_copy / "csv" / "00_contact_search.csv").exists()


def test_open_step_reads_a_chunk_at_a_time(tmp_path):
    import tracemalloc

    path = tmp_path / "big.h5"
    compressed_zeros(path, 2**25)  # 256 MiB a column
    tracemalloc.start()
    try:
        from gelrig.instrument.core.store import open_step

        rows = 0
        with open_step(path) as step:
            assert step.rows == 2**25 and step.names == ["t_s", "force_N"]
            for block in step.chunks(1 << 20):
                rows += block["t_s"].size
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert rows == 2**25
    assert peak < 40e6, peak  # two 8 MB chunks and the reading's temporaries


def test_export_refuses_a_csv_bigger_than_the_free_space(run_copy, monkeypatch, capsys):
    import shutil as shutil_module
    from collections import namedtuple

    from gelrig.cli import main

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil_module, "disk_usage", lambda _path: usage(10**9, 0, 10**5))
    assert main(["export", str(run_copy), "--csv"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--out = " in err and "has 0.0 GB free" in err
    assert "takes up to" in err and "as CSV" in err
    assert not list((run_copy / "csv").glob("*.csv*"))  # nothing written


@pytest.mark.parametrize("command", ["export", "analyze"])
def test_an_out_name_longer_than_the_file_system_allows(run_copy, tmp_path, command):
    out = tmp_path / ("x" * 300)
    args = [run_copy, "--csv", "--out", out] if command == "export" else [run_copy, "--out", out]
    code, stdout, err = gelrig(command, *args)
    assert code == 2, (stdout, err)
    assert err.strip() == (f'gelrig: error: --out = "{"x" * 37}...": a name of 300 bytes; the '
                           "file system allows at most 255 bytes a name")
