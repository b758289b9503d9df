"""`gelrig plan` rehearses the protocol on the rig's twin: each finding of issue 12 is caught
with exit 2 and one line naming the step and the cap; the paper protocols pass with the exact
lab time a real virtual run records."""

from __future__ import annotations

from pathlib import Path

import pytest

from gelrig.cli import main
from gelrig.protocols.rigfile import default_rig

SEARCH = """
[[step]]
kind = "compression_contact_search"
name = "probe"
confirm = 0
speed = "{speed}"
"""
HOLD = """
[[step]]
kind = "ramp_hold"
diameter = "18.63 mm"
name = "squeeze"
hold = "5 s"
rate = "100 Hz"
terms = 1
"""
SHEAR_SEARCH = """
[[step]]
kind = "shear_contact_search"
name = "touch"
safe_gap = "4 mm"
sweep = "70 mm"
touch_passes = 2
"""
LADDER = """
[[step]]
kind = "speed_ladder"
name = "ladder"
overlaps = 1
first_overlap = "{first}"
speeds = [{speeds}]
travel = "2 mm"
wait = "1 s"
"""


def write(tmp_path: Path, name: str, text: str) -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def protocol(tmp_path: Path, rig: str, *steps: str) -> str:
    head = f'[protocol]\nname = "t"\nrig = "{rig}"\n'
    return write(tmp_path, "p.toml", head + "".join(steps))


def rig(tmp_path: Path, kind: str, *edits: tuple[str, str]) -> str:
    text = default_rig(kind).read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    return write(tmp_path, f"{kind}.toml", text)


def plan(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["plan", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_probe_speed_above_the_stage_cap(tmp_path, capsys):
    p = protocol(tmp_path, "compression", SEARCH.format(speed="1.31 mm/s"), HOLD)
    r = rig(tmp_path, "compression", ('max_velocity = "2.3 mm/s"', 'max_velocity = "1 mm/s"'))
    code, _out, err = plan(capsys, p, "--rig", r)
    assert code == 2
    line = one_line(err)
    assert "step 0 (probe)" in line and "1.31 mm/s" in line and "max_velocity 1 mm/s" in line
    assert "refused before anything moves" in line


def test_ladder_speed_above_the_rheometer_maximum(tmp_path, capsys):
    p = protocol(tmp_path, "shear", SHEAR_SEARCH,
                 LADDER.format(first="0.4 mm", speeds='"2.38e-5 m/s", "6 mm/s"'))
    code, _, err = plan(capsys, p)
    assert code == 2
    line = one_line(err)
    assert "step 1 (ladder)" in line and "6 mm/s above the rheometer's max_speed 5 mm/s" in line


def test_first_overlap_the_gap_cannot_reach(tmp_path, capsys):
    p = protocol(tmp_path, "shear", SHEAR_SEARCH,
                 LADDER.format(first="3.5 mm", speeds='"2.38e-5 m/s"'))
    r = rig(tmp_path, "shear", ('overlap_limit = "1.2 mm"', 'overlap_limit = "5 mm"'),
            ('max_overlap = "1.2 mm"', 'max_overlap = "5 mm"'))
    code, out, err = plan(capsys, p, "--rig", r)
    assert code == 2
    line = one_line(err)
    assert line.startswith("gelrig plan: step 1 (ladder) at ")  # found after the search ran
    assert "gap_min 0 mm" in line and "cannot reach" in line
    assert "0. touch: completed" in out
    assert "cannot reach" not in out  # the failure is said once, on stderr (issue 27)


def test_ramp_hold_without_a_search(tmp_path, capsys):
    code, _, err = plan(capsys, protocol(tmp_path, "compression", HOLD))
    assert code == 2
    assert "step 0 (squeeze): ramp_hold needs first_touch, or a contact search" in one_line(err)


def test_travel_beyond_max_position(tmp_path, capsys):
    p = protocol(tmp_path, "compression", SEARCH.format(speed="0.3 mm/s"), HOLD)
    r = rig(tmp_path, "compression", ('max_position = "12 mm"', 'max_position = "7 mm"'))
    code, out, err = plan(capsys, p, "--rig", r)
    assert code == 2
    line = one_line(err)
    assert line.startswith("gelrig plan: step 1 (squeeze) at ")
    assert "beyond the stage's travel [0, 7] mm ([stage] max_position)" in line
    assert "0. probe: completed" in out


@pytest.mark.parametrize("name", ["x" * 300, "a\x00b"])
def test_step_names_that_cannot_be_file_names(tmp_path, capsys, name):
    step = SEARCH.format(speed="0.3 mm/s").replace('name = "probe"', f'name = "{name}"'
                                                   .replace("\x00", "\\u0000"))
    code, out, err = plan(capsys, protocol(tmp_path, "compression", step))
    assert code == 2
    line = one_line(err)
    assert "[step[0]] name" in line and "at most 80 characters" in line
    assert "Rehearsal" not in out  # refused at load: nothing ran


def test_a_step_name_with_path_separators_names_a_file_inside_the_run(tmp_path, capsys):
    """Names may carry units ("1 um/s"): the data file is a slug of the name, inside steps/."""
    step = SEARCH.format(speed="0.3 mm/s").replace('name = "probe"', 'name = "runs/../../etc"')
    out = tmp_path / "run"
    from gelrig.cli import main

    assert main(["run", str(protocol(tmp_path, "compression", step)), "--out", str(out)]) == 0
    files = sorted(p.relative_to(out) for p in out.rglob("*.h5"))
    assert [str(f) for f in files] == ["steps/00_runs_.._.._etc.h5"]


def test_paper_compression_rehearses_to_the_lab_time_of_a_real_run(tmp_path, capsys):
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.instrument.core.store import RunDirectory
    from gelrig.protocols.rigfile import load_rig
    from gelrig.protocols.spec import load_protocol, paper_protocol
    from gelrig.terminal import record_run

    code, out, err = plan(capsys, "paper:compression", "--out", str(tmp_path / "runs"))
    assert code == 0, err
    assert "rehearsal passed" in out and "3,000,000 samples" in out  # header, unchanged
    run = RunDirectory.create(tmp_path / "real", {})
    state, _ = record_run(load_protocol(paper_protocol("compression")),
                       load_rig(default_rig("compression")), VirtualClock(), run, show=False)
    assert state.value == "completed"
    for step in run.read_metadata()["steps"]:
        lab = step["finished"] - step["started"]
        assert f"{step['index']}. {step['name']}: completed in {lab:.2f} s" in out
        assert f"{step['samples']:,} samples" in out


def test_shear_rehearses_to_the_lab_time_of_a_real_run(tmp_path, capsys):
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.instrument.core.store import RunDirectory
    from gelrig.protocols.rigfile import load_rig
    from gelrig.protocols.spec import load_protocol
    from gelrig.terminal import record_run

    p = protocol(tmp_path, "shear", SHEAR_SEARCH,
                 LADDER.format(first="0.4 mm", speeds='"2.38e-5 m/s", "2.37e-4 m/s"'))
    code, out, err = plan(capsys, p)
    assert code == 0, err
    run = RunDirectory.create(tmp_path / "real", {})  # the real run goes over TCP
    state, _ = record_run(load_protocol(p), load_rig(default_rig("shear")), VirtualClock(), run,
                       show=False)
    assert state.value == "completed"
    for step in run.read_metadata()["steps"]:
        lab = step["finished"] - step["started"]
        assert f"{step['index']}. {step['name']}: completed in {lab:.2f} s" in out
        assert f"{step['samples']:,} samples" in out


def test_a_full_disk_is_warned_about(tmp_path, monkeypatch):
    import shutil

    from gelrig.commands.run import disk_warning

    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda _: usage._replace(free=10**6))
    assert disk_warning(tmp_path / "runs" / "new", 5 * 10**6).startswith("WARNING: output disk")
    assert not disk_warning(tmp_path, 10**5).startswith("WARNING")


@pytest.mark.parametrize(("steps", "expected"), [
    # 7 days at 20 kHz: 1.2e10 samples (every field within its own range)
    (HOLD.replace('"5 s"', '"604800 s"').replace('"100 Hz"', '"20000 Hz"'),
     'samples per run = "12,09'),
    # 12 holds of 7 days at 100 Hz: 84 days of lab time, 7.3e8 samples
    (HOLD.replace('"5 s"', '"604800 s"') * 12, 'lab time per run = "84.'),
    ("".join(HOLD for _ in range(1000)), '[[step]] = "1,001 tables": at most 1000 steps'),
    (LADDER.format(first="0.4 mm", speeds=", ".join(['"1 mm/s"'] * 10**6)),
     '[step[1]] speeds = "1,000,000 values": at most 100 values'),
])
def test_protocols_beyond_the_bounds_are_refused_before_the_rehearsal(tmp_path, capsys, steps,
                                                                       expected):
    import time

    kind = "shear" if "speed_ladder" in steps else "compression"
    p = protocol(tmp_path, kind, SEARCH.format(speed="0.3 mm/s") if kind == "compression"
                 else SHEAR_SEARCH, steps)
    start = time.monotonic()
    code, out, err = plan(capsys, p)
    assert code == 2
    line = one_line(err)
    assert line.startswith(f"gelrig: error: {p}: ") and expected in line, line
    assert "Rehearsal" not in out  # refused before the twin is built
    assert time.monotonic() - start < 60  # was: 10.6 GB and no answer, or 200-300 s


@pytest.mark.parametrize("command", [["plan", "paper:compression"], ["run", "paper:compression"],
                                     ["campaign", "campaign.toml"]])
def test_an_out_name_longer_than_the_file_system_allows(tmp_path, capsys, command):
    """Was: an OSError traceback (File name too long)."""
    out = tmp_path / ("y" * 300) / "x"
    code = main([*command, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err == (f'gelrig: error: --out = "{"y" * 37}...": a name of 300 bytes; the file '
                   "system allows at most 255 bytes a name")
