"""Wire log and replay (issue 30): a short compression run recorded exchange by exchange,
then replayed through the same drivers with no instrument behind them, gives the same data."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from gelrig.instrument.core import wire
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import record_run

STEPS = [{"kind": "compression_contact_search", "name": "contact search", "probe": "0.5 mm",
          "speed": "0.3 mm/s", "threshold": "5 mN", "retract": "0.5 mm", "confirm": 2,
          "rate": "100 Hz"},
         {"kind": "ramp_hold", "diameter": "18.63 mm", "name": "ramp and hold", "hold": "5 s",
          "rate": "100 Hz", "terms": 1}]


def _run(folder, name):
    protocol = parse_protocol({"protocol": {"name": "touch", "rig": "compression"},
                               "step": STEPS})
    spec = load_rig(default_rig("compression"))
    run = RunDirectory.create(folder / name, {"protocol": protocol.table, "rig": spec.table})
    state, _ = record_run(protocol, spec, VirtualClock(), run, show=False)
    return state, run.path


def _columns(path):
    out = {}
    for f in sorted((path / "steps").glob("*.h5")):
        with h5py.File(f) as h5:
            for name in h5:
                if isinstance(h5[name], h5py.Dataset):
                    out[f"{f.name}/{name}"] = h5[name][()]
    return out


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("wire")
    with wire.recording(wire.WireLog(folder / "wire.jsonl", {"argv": ["test"]})) as log:
        state, path = _run(folder, "original")
    assert state is RunState.COMPLETED
    return folder, path, log


def test_a_replayed_run_gives_the_same_data_and_uses_every_exchange(recorded):
    folder, original, log = recorded
    assert log.records > 1000 and not log.full
    replay = wire.Replay(log.path)
    with wire.replaying(replay):
        state, path = _run(folder, "replay")
    assert state is RunState.COMPLETED
    assert replay.left() == {}
    assert replay.served() == replay.recorded
    assert set(replay.recorded) == {"kdc101", "usb6001"}
    first, again = _columns(original), _columns(path)
    assert first.keys() == again.keys() and len(first) >= 12
    for key, values in first.items():
        assert np.array_equal(values, again[key], equal_nan=True), key


def test_a_replay_that_diverges_says_where(recorded, tmp_path):
    _, _, log = recorded
    lines = log.path.read_text().splitlines()
    # the recording's first stage write (HW_NO_FLASH_PROGRAMMING) becomes another message
    at = next(i for i, line in enumerate(lines) if '"k":"write"' in line)
    lines[at] = lines[at].replace('"b":"180000005001"', '"b":"050000005001"')
    changed = tmp_path / "changed.jsonl"
    changed.write_text("\n".join(lines) + "\n")
    replay = wire.Replay(changed)
    with wire.replaying(replay), pytest.raises(Exception) as err:
        _run(tmp_path, "diverged")
    text = str(err.value)
    assert "kdc101 call 2 at recorded host time 0.100000 s" in text
    assert "the driver sent write '180000005001'" in text
    assert "the recording has write '050000005001'" in text


def test_a_log_is_bounded(tmp_path):
    log = wire.WireLog(tmp_path / "w.jsonl", max_bytes=600)
    for i in range(100):
        log.add("kdc101", "write", i, i, b="00" * 10)
    log.close()
    text = (tmp_path / "w.jsonl").read_text()
    assert log.full and len(text) <= 600
    assert text.rstrip().endswith(f'"records":{log.records}}}')
    replay = wire.Replay(tmp_path / "w.jsonl")
    assert replay.truncated and replay.recorded["kdc101"] == log.records


PROTOCOL = """\
[protocol]
name = "touch"
rig = "compression"

[sample]
name = "gel"
diameter = "18.63 mm"

[[step]]
kind = "compression_contact_search"
name = "contact search"
probe = "0.5 mm"
speed = "0.3 mm/s"
threshold = "5 mN"
retract = "0.5 mm"
confirm = 2
rate = "100 Hz"

[[step]]
kind = "ramp_hold"
name = "ramp and hold"
hold = "5 s"
rate = "100 Hz"
terms = 1
"""


@pytest.mark.slow
def test_gelrig_run_wire_log_then_sim_replay(tmp_path, capsys, monkeypatch):
    from gelrig.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "touch.toml").write_text(PROTOCOL)
    assert main(["run", "touch.toml", "--out", "run1", "--wire-log", "--no-rehearse"]) == 0
    log = tmp_path / "run1" / "wire.jsonl"
    assert log.is_file() and not list(tmp_path.glob(".*wire.jsonl"))
    capsys.readouterr()
    assert main(["sim", "replay", str(log)]) == 0
    out = capsys.readouterr().out
    assert "recorded exchanges served, every one as recorded" in out
    first, again = _columns(tmp_path / "run1"), _columns(tmp_path / "run1-replay")
    assert first.keys() == again.keys()
    assert all(np.array_equal(v, again[k], equal_nan=True) for k, v in first.items())


def test_sim_replay_of_something_else_is_one_line_exit_2(tmp_path, capsys):
    from gelrig.cli import main

    log = tmp_path / "w.jsonl"
    wire.WireLog(log, {"argv": ["plan", "paper:compression"]}).close()
    assert main(["sim", "replay", str(log)]) == 2
    err = capsys.readouterr().err.strip()
    assert "recorded by gelrig run --wire-log" in err and "\n" not in err
    assert main(["sim", "replay", str(tmp_path / "missing.jsonl")]) == 2


SHEAR = """\
[protocol]
name = "shear touch"
rig = "shear"

[sample]
name = "paper: PDMS spheres"
r1 = "9.2 mm"
r2 = "9.96 mm"

[[step]]
kind = "shear_contact_search"
name = "contact search"
safe_gap = "4 mm"
coarse = "1 mm"
fine = "0.1 mm"
rpm = 0.5
threshold = "0.2 mN*m"
sweep = "70 mm"
"""


@pytest.mark.slow
def test_a_shear_runs_mcr501_lines_replay_the_same(tmp_path, capsys, monkeypatch):
    from gelrig.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "shear.toml").write_text(SHEAR)
    assert main(["run", "shear.toml", "--out", "srun", "--wire-log", "--no-rehearse"]) == 0
    log = tmp_path / "srun" / "wire.jsonl"
    assert wire.Replay(log).recorded.keys() == {"mcr501"}
    capsys.readouterr()
    assert main(["sim", "replay", str(log), "--out", "again"]) == 0
    assert "every one as recorded" in capsys.readouterr().out
    first, again = _columns(tmp_path / "srun"), _columns(tmp_path / "again")
    assert first.keys() == again.keys() and first
    assert all(np.array_equal(v, again[k], equal_nan=True) for k, v in first.items())
