"""Disk full while recording, resume (in place and --out), the run lock, and bad input that
must end in one line: --out, model --dt, instrument addresses, rig files."""

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from gelrig.cli import main
from gelrig.instrument.core.store import RESERVE_NAME, RunDirectory, read_step
from gelrig.protocols.rigfile import default_rig
from tests.samples import SHORT_COMPRESSION

SHORT = SHORT_COMPRESSION

#: The CLI with every file it writes limited to LIMIT bytes (EFBIG past it, as on a full
#: disk) and a flush after every block, so the fault comes while samples arrive.
LIMITED = textwrap.dedent("""
    import resource, signal, sys
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    limit = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    import gelrig.instrument.core.store as store
    store.FLUSH_INTERVAL = 0.0
    from gelrig.cli import main
    sys.exit(main(sys.argv[2:]))
""")
LIMIT = 1_000_000


def one_error_line(capsys):
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    err = captured.err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def leftovers(run: Path) -> list[Path]:
    return [p for p in run.rglob("*") if p.name.endswith((".tmp", ".sealing", ".part"))
            or p.name == RESERVE_NAME]


@pytest.fixture(scope="module")
def disk_full_run(tmp_path_factory):
    """A run whose hold hit the file size limit; kept unchanged for the module's tests."""
    base = tmp_path_factory.mktemp("full")
    protocol = base / "short.toml"
    protocol.write_text(SHORT.format(hold="300 s"))
    out = base / "run"
    proc = subprocess.run([sys.executable, "-c", LIMITED, str(LIMIT), "run", str(protocol),
                           "--out", str(out)], capture_output=True, text=True, timeout=180,
                          stdin=subprocess.DEVNULL)
    return out, proc


@pytest.fixture
def full_copy(disk_full_run, tmp_path):
    target = tmp_path / "run"
    shutil.copytree(disk_full_run[0], target)
    return target


def test_disk_full_fails_the_run_in_one_line_and_keeps_the_data(disk_full_run):
    out, proc = disk_full_run
    assert proc.returncode == 1, proc.stderr[-2000:]  # failed, not a crash (139)
    assert "Traceback" not in proc.stdout + proc.stderr
    meta = RunDirectory(out).read_metadata()
    assert meta["status"] == "failed"
    line = meta["storage_fault"]
    assert line.startswith("file size limit reached writing steps/01_ramp_and_hold.h5: ")
    assert line in proc.stderr and "resume" in proc.stderr
    kept = read_step(out / "steps" / "01_ramp_and_hold.h5")["t_s"].size
    assert kept > 0 and line.endswith(f": {kept:,} samples kept")
    steps = meta["steps"]
    assert [s["status"] for s in steps] == ["completed", "failed"]
    assert steps[1]["samples"] == kept
    assert meta["faults"][0]["kind"] == "StorageFault"
    assert leftovers(out) == []
    assert os.path.getsize(out / "steps" / "01_ramp_and_hold.h5") <= LIMIT


def test_resume_in_place_once_there_is_room(full_copy):
    kept = read_step(full_copy / "steps" / "01_ramp_and_hold.h5")["t_s"].size
    assert main(["resume", str(full_copy), "--clock", "virtual"]) == 0
    meta = RunDirectory(full_copy).read_metadata()
    assert meta["status"] == "completed" and meta.get("storage_fault") is None
    assert [s["status"] for s in meta["steps"]] == ["completed", "completed"]
    attempt = meta["interrupted_steps"][0]
    assert attempt["status"] == "failed" and "attempt-1" in attempt["file"]
    assert read_step(full_copy / attempt["file"])["t_s"].size == kept
    assert leftovers(full_copy) == []


def test_resume_out_continues_in_a_new_directory(full_copy, tmp_path):
    before = (full_copy / "run.json").read_text()
    new = tmp_path / "elsewhere" / "run"
    assert main(["resume", str(full_copy), "--out", str(new), "--clock", "virtual"]) == 0
    assert (full_copy / "run.json").read_text() == before  # the full disk is left alone
    meta = RunDirectory(new).read_metadata()
    assert meta["status"] == "completed" and meta["copied_from"] == [str(full_copy.resolve())]
    assert (new / "steps" / "00_contact_search.h5").read_bytes() == (
        full_copy / "steps" / "00_contact_search.h5").read_bytes()
    assert read_step(new / meta["interrupted_steps"][0]["file"])["t_s"].size > 0
    assert leftovers(new) == []


def test_resume_out_refuses_a_folder_in_use(full_copy, tmp_path, capsys):
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main(["resume", str(full_copy), "--out", str(other)]) == 2
    assert "is a folder with other files in it" in one_error_line(capsys)
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]


def test_a_second_resume_names_the_holder(full_copy, capsys):
    run = RunDirectory(full_copy)
    with run.lock():
        assert main(["resume", str(full_copy), "--clock", "virtual"]) == 2
        line = one_error_line(capsys)
    assert f"is in use by process {os.getpid()}" in line and str(full_copy) in line
    assert run.read_metadata()["status"] == "failed"  # untouched
    assert main(["resume", str(full_copy), "--clock", "virtual"]) == 0  # free again


def test_a_second_resume_in_another_process(full_copy):
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from gelrig.instrument.core.store import RunDirectory\n"
         "with RunDirectory(sys.argv[1]).lock():\n print('held', flush=True); time.sleep(60)",
         str(full_copy)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        proc = subprocess.run([sys.executable, "-m", "gelrig.cli", "resume", str(full_copy)],
                              capture_output=True, text=True, timeout=60)
    finally:
        holder.kill()
        holder.wait(30)
        holder.stdout.close()
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert f"is in use by process {holder.pid}" in proc.stderr.strip()


def test_recorder_fault_stops_motion_in_process(tmp_path, monkeypatch):
    """ENOSPC from HDF5 mid-step: the runner stops all motion and the run ends failed."""
    import errno

    import h5py

    from gelrig.factory import build_rig
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.protocols.events import RunState
    from gelrig.protocols.host import RunHost
    from gelrig.protocols.rigfile import load_rig
    from gelrig.protocols.spec import parse_protocol

    path = tmp_path / "p.toml"
    path.write_text(SHORT.format(hold="60 s"))
    import tomllib
    protocol = parse_protocol(tomllib.loads(path.read_text()), str(path))
    rig = build_rig(load_rig(default_rig("compression")), VirtualClock())
    stops = []
    real_stop = rig.stop_all
    monkeypatch.setattr(rig, "stop_all", lambda: (stops.append(1), real_stop())[1])
    flushes = {"n": 0}
    real_flush = h5py.Dataset.flush

    def flush(self):
        if "ramp" in self.file.filename:
            flushes["n"] += 1
            if flushes["n"] > 10:
                raise OSError(errno.ENOSPC, "No space left on device")
        return real_flush(self)

    monkeypatch.setattr(h5py.Dataset, "flush", flush)
    monkeypatch.setattr("gelrig.instrument.core.store.FLUSH_INTERVAL", 0.0)
    run = RunDirectory.create(tmp_path / "run", {})
    try:
        with RunHost(rig, protocol, run) as host:
            state = host.run()
    finally:
        rig.close()
    assert state is RunState.FAILED and stops
    meta = run.read_metadata()
    assert meta["status"] == "failed"
    assert meta["storage_fault"].startswith("disk full writing steps/01_ramp_and_hold.h5: ")
    monkeypatch.undo()
    kept = read_step(run.path / "steps" / "01_ramp_and_hold.h5")["t_s"].size
    assert kept > 0 and meta["steps"][1]["samples"] == kept
    assert leftovers(run.path) == []


def test_tmpfs_disk_full(tmp_path):
    """The same on a real full file system (needs root and mount; skipped elsewhere)."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs",
                                            str(mnt)], capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    try:
        protocol = tmp_path / "p.toml"
        protocol.write_text(SHORT.format(hold="300 s"))
        proc = subprocess.run([sys.executable, "-c", LIMITED, str(1 << 40), "run",
                               str(protocol), "--out", str(mnt / "run")], capture_output=True,
                              text=True, timeout=180)
        assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
        meta = json.loads((mnt / "run" / "run.json").read_text())
        assert meta["status"] == "failed" and meta["storage_fault"].startswith("disk full")
        assert leftovers(mnt / "run") == []
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


# -- bad input: one line, exit 2 ------------------------------------------------------------

@pytest.fixture
def short(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(SHORT.format(hold="60 s"))
    return path


def test_out_is_a_file(tmp_path, short, capsys):
    target = tmp_path / "a-file"
    target.write_text("x")
    assert main(["run", str(short), "--out", str(target)]) == 2
    assert "--out" in (line := one_error_line(capsys)) and "is a file" in line
    assert target.read_text() == "x"


def test_out_is_a_folder_that_is_not_a_run(tmp_path, short, capsys):
    folder = tmp_path / "photos"
    folder.mkdir()
    (folder / "a.jpg").write_text("x")
    assert main(["run", str(short), "--out", str(folder)]) == 2
    assert "is a folder with other files in it" in one_error_line(capsys)
    assert [p.name for p in folder.iterdir()] == ["a.jpg"]


@pytest.mark.parametrize("command", [["export", "{run}", "--csv", "--out", "{file}"],
                                     ["analyze", "{run}", "--out", "{file}"]])
def test_export_and_analyze_out_is_a_file(tmp_path, capsys, command):
    run = RunDirectory.create(tmp_path / "r", {})
    target = tmp_path / "f"
    target.write_text("x")
    args = [a.format(run=run.path, file=target) for a in command]
    assert main(args) == 2
    assert "is a file, not a folder" in one_error_line(capsys)


@pytest.mark.parametrize("args", [
    ["compression", "--radius", "9 mm", "--depth", "1 mm", "--rate", "37 um/s", "--hold",
     "3000", "--g-e", "4 kPa", "--dt", "1e-12"],
    ["shear", "--r1", "9 mm", "--r2", "10 mm", "--delta-max", "0.5 mm", "--speed", "1e-4",
     "--g-e", "4 kPa", "--dt", "1e-12"],
])
def test_model_dt_too_small(tmp_path, capsys, args):
    out = tmp_path / "m.csv"
    assert main(["model", *args, "--out", str(out)]) == 2
    line = one_error_line(capsys)
    assert "--dt = 1e-12" in line and "at most 1e+08" in line and not out.exists()


def rig_with(tmp_path, replace):
    text = default_rig("compression").read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return path


FORCE_SIM = '[force]\ntransport = "simulator"'


def test_unreachable_grpc_names_the_field(tmp_path, short, capsys):
    rig = rig_with(tmp_path, [(FORCE_SIM, '[force]\ntransport = "grpc"\n'
                                          'address = "grpc://127.0.0.1:1"')])
    out = tmp_path / "r"
    assert main(["run", str(short), "--rig", str(rig), "--clock", "real", "--out",
                 str(out)]) == 2
    line = one_error_line(capsys)
    assert 'rig.toml: [force] address = "grpc://127.0.0.1:1": cannot connect: tried the NI ' \
           "gRPC Device Server at grpc://127.0.0.1:1" in line
    assert not out.exists()  # nothing was recorded, nothing is left


def test_unreachable_serial_port_names_the_field(tmp_path, short, capsys):
    rig = rig_with(tmp_path, [('[stage]\ntransport = "simulator"',
                               '[stage]\ntransport = "serial"\naddress = "/dev/ttyNOPE9"'),
                              (FORCE_SIM, '[force]\ntransport = "grpc"\n'
                                          'address = "grpc://127.0.0.1:1"')])
    assert main(["run", str(short), "--rig", str(rig), "--clock", "real", "--out",
                 str(tmp_path / "r")]) == 2
    line = one_error_line(capsys)
    assert '[stage] address = "/dev/ttyNOPE9": cannot connect: tried serial port' in line


@pytest.mark.parametrize("address", ["grpc://nohost:notaport", "grpc://host", "grpc://:80",
                                     "grpc://host:70000", "grpc://host:1:2"])
def test_malformed_grpc_address_at_load(tmp_path, short, capsys, address):
    rig = rig_with(tmp_path, [(FORCE_SIM, f'[force]\ntransport = "grpc"\naddress = "{address}"')])
    assert main(["plan", str(short), "--rig", str(rig)]) == 2
    line = one_error_line(capsys)
    assert f'rig.toml: [force] address = "{address}": allowed: grpc://HOST:PORT' in line


def test_good_grpc_address_loads(tmp_path, short):
    from gelrig.protocols.rigfile import load_rig

    rig = rig_with(tmp_path, [(FORCE_SIM, '[force]\ntransport = "grpc"\n'
                                          'address = "grpc://daq-pc.lab:31763"')])
    assert load_rig(rig).force.address == "grpc://daq-pc.lab:31763"


# -- already on main, held here --------------------------------------------------------------

@pytest.mark.parametrize("encode,expected", [
    (lambda t: t.encode("utf-16"), "UTF"),
    (lambda t: t.encode("utf-8") + b"\n# \xff\xfe\n", "UTF-8"),
])
def test_rig_file_encoding(tmp_path, short, capsys, encode, expected):
    rig = tmp_path / "rig.toml"
    rig.write_bytes(encode(default_rig("compression").read_text()))
    assert main(["plan", str(short), "--rig", str(rig)]) == 2
    line = one_error_line(capsys)
    assert "rig.toml" in line and expected in line


def test_deeply_nested_protocol(tmp_path, capsys):
    path = tmp_path / "deep.toml"
    path.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    assert main(["plan", str(path)]) == 2
    assert "deep.toml" in one_error_line(capsys)


def test_unknown_visa_backend(tmp_path, capsys):
    text = default_rig("shear").read_text().replace("[rheometer]", '[rheometer]\nbackend = "@ni"',
                                                    1)
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    assert main(["plan", "paper:shear", "--rig", str(rig)]) == 2
    assert '[rheometer] backend = "@ni"' in one_error_line(capsys)
