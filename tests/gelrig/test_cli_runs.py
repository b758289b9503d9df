"""Run metadata and the catalog of runs end to end (issue 28, ADR 0370): three short runs
with samples and operators on the built-in simulated compression rig and one killed by
SIGKILL, listed and filtered by ``gelrig runs``, the index rebuilt, a corrupt or locked index
that stops no run, ``--compare``, ``gelrig.runs()`` and ``gelrig.load_run()``."""

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import gelrig
from gelrig.cli import main
from gelrig.instrument.core.catalog import CATALOG_NAME
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.rigfile import default_rig
from tests.samples import SHORT_COMPRESSION

ROOT = Path(__file__).resolve().parents[2]


def _short(folder: Path, hold: str) -> Path:
    path = folder / f"short-{hold.replace(' ', '')}.toml"
    path.write_text(SHORT_COMPRESSION.format(hold=hold))
    return path


def _fast_rig(folder: Path) -> Path:
    """The built-in rig with a 5 s relaxation: a 30 s hold resolves its 1-term fit."""
    text = default_rig("compression").read_text()
    old = 'relax = [["630 Pa", "1413 s"]]'
    assert old in text
    path = folder / "fast.toml"
    path.write_text(text.replace(old, 'relax = [["3000 Pa", "5 s"]]'))
    return path


def _run(*argv: str) -> int:
    return main(["run", *argv, "--no-rehearse"])


def _killed(protocol: Path, out: Path) -> None:
    """``gelrig run`` in a subprocess, killed by SIGKILL in the middle of its hold."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "gelrig.cli", "run", str(protocol), "--out", str(out),
         "--clock", "paced:20", "--no-rehearse", "--sample", "gel-K9", "--operator", "cy"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    run = RunDirectory(out)
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            try:
                steps = run.read_metadata()["steps"]
                flushed = len(steps) >= 2 and run.read_step(1)["t_s"].size > 0
            except Exception:
                flushed = False
            if flushed:
                break
            time.sleep(0.1)
        else:
            raise AssertionError("the run never reached its hold")
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """``runs/`` with three completed runs (default folder names) and one killed."""
    home = tmp_path_factory.mktemp("lab")
    short, long = _short(home, "20 s"), _short(home, "300 s")
    fast = _fast_rig(home)
    before = Path.cwd()
    os.chdir(home)
    try:
        assert _run(str(short), "--sample", "gel-A1", "--operator", "ada", "--tag", "week48",
                    "--note", "first of the batch") == 0
        assert _run(str(_short(home, "30 s")), "--rig", str(fast), "--sample", "gel-A1",
                    "--operator", "bo", "--tag", "week48", "--tag", "fast") == 0
        assert _run(str(short), "--sample", "gel-B2", "--operator", "ada") == 0
    finally:
        os.chdir(before)
    root = home / "runs"
    _killed(long, root / "killed")
    return root


def _warnings(capsys) -> list[str]:
    """stderr's lines but the progress bars."""
    return [line for line in capsys.readouterr().err.splitlines()
            if line.startswith("gelrig")]


def _listed(capsys, *argv: str) -> list[dict]:
    capsys.readouterr()
    assert main(["runs", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_run_json_records_the_metadata_and_the_folder_names_the_sample(lab):
    names = sorted(p.name for p in lab.iterdir() if p.is_dir())
    assert [n.endswith("-gel-A1-compression") for n in names[:2]] == [True, True]
    assert names[2].endswith("-gel-B2-compression") and names[3] == "killed"
    meta = json.loads((lab / names[0] / "run.json").read_text())
    assert meta["sample"]["name"] == "gel-A1"
    assert meta["sample"]["diameter"] == pytest.approx(0.01863)  # the protocol's size kept
    assert (meta["operator"], meta["note"], meta["tags"]) == ("ada", "first of the batch",
                                                              ["week48"])
    assert meta["finished_wall"]


def test_runs_lists_every_run_with_its_status(lab, capsys):
    runs = _listed(capsys, str(lab))
    by_name = {r["name"]: r for r in runs}
    assert len(runs) == 4
    killed = by_name["killed"]
    assert killed["status"] == "interrupted" and killed["recorded_status"] == "running"
    assert (killed["sample"], killed["operator"]) == ("gel-K9", "cy")
    done = [r for r in runs if r["name"] != "killed"]
    assert [r["status"] for r in done] == ["completed"] * 3
    for r in runs:
        assert {"path", "sample", "operator", "protocol", "status", "started",
                "finished", "results"} <= set(r)
        assert r["protocol"] == "short compression"
    fast = next(r for r in done if r["operator"] == "bo")
    g_e = fast["results"]["ramp and hold/1-term G_e"]
    assert g_e["unit"] == "Pa" and g_e["lo"] < g_e["value"] < g_e["hi"]
    assert 6000 < g_e["value"] < 8000


def test_filters(lab, capsys):
    assert {r["sample"] for r in _listed(capsys, str(lab), "--sample", "gel-A1")} == {"gel-A1"}
    assert len(_listed(capsys, str(lab), "--sample", "gel-A1")) == 2
    assert len(_listed(capsys, str(lab), "--sample", "GEL-*")) == 4
    assert [r["name"] for r in _listed(capsys, str(lab), "--status", "interrupted")] == [
        "killed"]
    assert [r["operator"] for r in _listed(capsys, str(lab), "--operator", "bo")] == ["bo"]
    assert len(_listed(capsys, str(lab), "--tag", "week48")) == 2
    assert len(_listed(capsys, str(lab), "--tag", "week48", "--tag", "fast")) == 1
    assert len(_listed(capsys, str(lab), "--since", "1d")) == 4
    assert _listed(capsys, str(lab), "--until", "2000-01-01") == []
    assert main(["runs", str(lab)]) == 0  # the table
    out = capsys.readouterr().out
    assert "gel-K9" in out and "interrupted" in out and "4 run(s)" in out


@pytest.mark.parametrize("argv,field", [
    (["--since", "yesterday"], "since"),
    (["--plot", "x.png"], "--plot"),
    (["--compare", "nope", "killed"], "--compare"),
])
def test_bad_options_are_one_line(lab, capsys, argv, field):
    capsys.readouterr()
    assert main(["runs", str(lab), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0], err


def test_runs_of_a_folder_that_is_not_there(tmp_path, capsys):
    assert main(["runs", str(tmp_path / "nowhere")]) == 2
    assert "ROOT" in capsys.readouterr().err


def test_the_index_deleted_is_rebuilt(lab, capsys):
    before = _listed(capsys, str(lab))
    (lab / CATALOG_NAME).unlink()
    after = _listed(capsys, str(lab))
    assert after == before
    assert (lab / CATALOG_NAME).is_file()


def test_compare_writes_its_table_and_plot(lab, capsys, tmp_path):
    names = sorted(p.name for p in lab.iterdir() if p.is_dir() and p.name != "killed")
    plot = tmp_path / "cmp.png"
    capsys.readouterr()
    assert main(["runs", str(lab), "--compare", *names[:2], "killed", "--plot",
                 str(plot)]) == 0
    out = capsys.readouterr().out
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b"\x89PNG"
    assert "1-term G_e" in out and "interrupted" in out and "[" in out  # intervals
    assert main(["runs", str(lab), "--compare", str(lab / names[0]), names[2]]) == 0
    assert (lab / "compare.png").is_file()


def test_python_runs_and_load_run(lab):
    df = gelrig.runs(lab, sample="gel-A1")
    assert list(df["sample"]) == ["gel-A1", "gel-A1"]
    assert "ramp and hold/1-term G_e" in df.columns
    assert "ramp and hold/1-term G_e lo" in df.columns
    run = gelrig.load_run(df.path.iloc[0])
    hold = run.steps["ramp and hold"]
    assert isinstance(hold.columns["force_N"], np.ndarray) and hold["force_N"].size > 1000
    assert hold.units["force_N"] == "N" and hold.units["t_s"] == "s"
    assert run.sample == "gel-A1" and run.status == "completed"
    killed = gelrig.load_run(lab / "killed")
    assert killed.status == "interrupted" and killed.steps["ramp and hold"]["t_s"].size > 0
    assert gelrig.runs(lab, status="interrupted").name.tolist() == ["killed"]
    with pytest.raises(gelrig.ConfigError, match="allowed filters"):
        gelrig.runs(lab, colour="red")


def test_the_example_finds_and_plots(lab, tmp_path, capsys):
    sys.path.insert(0, str(ROOT / "examples"))
    try:
        import find_and_compare
    finally:
        sys.path.remove(str(ROOT / "examples"))
    out = tmp_path / "holds.png"
    assert find_and_compare.main([str(lab), "gel-A1", "--out", str(out)]) == 0
    assert out.is_file() and "2 run(s) of gel-A1" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["a/b", "..", "x" * 81, "two\nlines"])
def test_a_sample_name_that_cannot_name_a_folder_is_one_line(tmp_path, capsys, name):
    out = tmp_path / "r"
    assert _run(str(_short(tmp_path, "20 s")), "--sample", name, "--out", str(out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sample" in err[0], err
    assert not out.exists()


def test_bad_operator_is_one_line(tmp_path, capsys):
    assert _run(str(_short(tmp_path, "20 s")), "--operator", "a\nb",
                "--out", str(tmp_path / "r")) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--operator" in err[0], err


def test_a_corrupt_index_stops_no_run_and_is_rebuilt(tmp_path, capsys):
    root = tmp_path / "runs"
    root.mkdir()
    (root / CATALOG_NAME).write_bytes(os.urandom(4096))
    capsys.readouterr()
    assert _run(str(_short(tmp_path, "20 s")), "--sample", "gel-A1",
                "--out", str(root / "one")) == 0
    err = _warnings(capsys)
    assert len(err) == 1 and "run index" in err[0] and "the run goes on" in err[0], err
    assert RunDirectory(root / "one").read_metadata()["status"] == "completed"
    assert main(["runs", str(root), "--json"]) == 0
    captured = capsys.readouterr()
    assert [r["sample"] for r in json.loads(captured.out)] == ["gel-A1"]
    assert "rebuilt" in captured.err
    with sqlite3.connect(root / CATALOG_NAME) as con:
        assert con.execute("SELECT sample FROM runs").fetchall() == [("gel-A1",)]


def test_a_locked_index_does_not_block_a_run(tmp_path, capsys):
    root = tmp_path / "runs"
    root.mkdir()
    assert main(["runs", str(root), "--json"]) == 0  # the index made, empty
    holder = sqlite3.connect(root / CATALOG_NAME, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        capsys.readouterr()
        started = time.monotonic()
        assert _run(str(_short(tmp_path, "20 s")), "--sample", "gel-L1",
                    "--out", str(root / "locked")) == 0
        took = time.monotonic() - started
        err = _warnings(capsys)
        assert len(err) == 1 and "locked" in err[0], err
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert took < 60
    assert RunDirectory(root / "locked").read_metadata()["status"] == "completed"
    assert [r["sample"] for r in _listed(capsys, str(root))] == ["gel-L1"]  # caught up


def test_resume_records_its_metadata_and_the_catalog_follows(lab, tmp_path, capsys):
    import shutil

    root = tmp_path / "runs"
    shutil.copytree(lab / "killed", root / "killed")
    (root / "killed" / "run.lock").write_text("")  # the copy has no holder
    assert [r["status"] for r in _listed(capsys, str(root))] == ["interrupted"]
    assert main(["resume", str(root / "killed"), "--clock", "virtual", "--operator", "dee",
                 "--tag", "resumed", "--sample", "gel-K10"]) == 0
    meta = RunDirectory(root / "killed").read_metadata()
    assert (meta["operator"], meta["tags"], meta["sample"]["name"]) == ("dee", ["resumed"],
                                                                        "gel-K10")
    with sqlite3.connect(root / CATALOG_NAME) as con:  # indexed by the run host as it ended
        assert con.execute("SELECT status, operator, sample FROM runs").fetchall() == [
            ("completed", "dee", "gel-K10")]


TINY_LADDER = """
[protocol]
name = "tiny ladder"
rig = "shear"

[sample]
name = "bead-S1"
r1 = "9.2 mm"
r2 = "9.96 mm"

[[step]]
kind = "speed_ladder"
name = "ladder"
overlaps = 1
first_overlap = "0.45 mm"
speeds = ["2.37e-4 m/s"]
travel = "14 mm"
wait = "5 s"
touch_gap = "3.012 mm"
centre_angle = 0.7993
"""


def test_compare_shear_runs_plots_forces_per_pass(tmp_path, capsys):
    from gelrig.compare import overlay_plot

    protocol = tmp_path / "ladder.toml"
    protocol.write_text(TINY_LADDER)
    root = tmp_path / "runs"
    for name in ("bead-S1", "bead-S2"):
        assert _run(str(protocol), "--sample", name, "--out", str(root / name)) == 0
    capsys.readouterr()
    assert main(["runs", str(root), "--compare", "bead-S1", "bead-S2"]) == 0
    assert "ladder/touch_gap_m" in capsys.readouterr().out
    path, notes = overlay_plot([gelrig.load_run(root / n) for n in ("bead-S1", "bead-S2")],
                               tmp_path / "shear.png")
    assert notes == [] and path.stat().st_size > 10_000


def test_the_api_records_operator_note_and_tags(tmp_path):
    root = tmp_path / "runs"
    with gelrig.open_rig("compression") as rig:
        result = rig.run(_short(tmp_path, "20 s"), out=root / "api", sample="gel-P1",
                         operator="ada", note="from Python", tags=["api", "api"])
        assert result.ok
        with rig.run_interactive(name="nb", out=root / "nb", sample={"diameter": "18.63 mm"},
                                 show=False, operator="bo", tags=["notebook"]) as run:
            run.step("compression_contact_search", confirm=0)
        with pytest.raises(gelrig.ConfigError, match="operator"):
            rig.run(_short(tmp_path, "20 s"), out=root / "bad", operator="two\nlines")
    meta = json.loads((root / "api" / "run.json").read_text())
    assert meta["sample"]["name"] == "gel-P1" and meta["sample"]["diameter"] == 0.01863
    assert (meta["operator"], meta["note"], meta["tags"]) == ("ada", "from Python", ["api"])
    df = gelrig.runs(root)
    assert df.set_index("name").loc["nb", "operator"] == "bo"
    assert gelrig.runs(root, tag="notebook").name.tolist() == ["nb"]
    assert not (root / "bad").exists()
