"""Crafted and damaged run directories: export and analyze end with exit 2 and one line."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from instrument.errors import ConfigError
from instrument.store import RunDirectory, check_metadata, check_step_file, read_step
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
    "run.json a FIFO": (lambda run: ((run / "run.json").unlink(), os.mkfifo(run / "run.json")),
                        "run.json = ",),
    "run.json deeply nested": (_deep, "nested too deeply"),
    "run.json not UTF-8": (lambda run: (run / "run.json").write_bytes(
        '{"steps": []}'.encode("utf-16")), "is not UTF-8 text"),
}


ANALYZED = ["run.json a list", "index a string", "absolute path", "symlink to /dev/zero",
            "FIFO", "not HDF5", "cut to half", "dims of 2^40"]


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
    with pytest.raises(ConfigError, match=r"declares 8,796,093,022,208 bytes"):
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
