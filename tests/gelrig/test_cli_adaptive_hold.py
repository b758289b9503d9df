"""An adaptive hold through the CLI on the built-in simulated compression rig (the paper's
plate material, tau = 1413 s, the rig file's noise): run.json, the CLI and gelrig analyze say
how and when the hold ended; bad values are one line and exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gelrig.cli import main
from tests.samples import SHORT_COMPRESSION

ADAPTIVE = SHORT_COMPRESSION + 'until = 0.02\nmin_hold = "{min_hold}"\n'


def test_adaptive_hold_run_and_analyze(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                       ) -> None:
    path = tmp_path / "adaptive.toml"
    path.write_text(ADAPTIVE.format(hold="3000 s", min_hold="300 s"))
    out = tmp_path / "runs"
    assert main(["run", str(path), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    run = out
    hold = json.loads((run / "run.json").read_text())["steps"][1]["results"]
    assert hold["hold_end"] == "target"
    assert 300.0 <= hold["held_s"] < 3000.0
    assert f"adaptive hold ended after {hold['held_s']:.0f} s (target met)" in err
    last = hold["live_fits"][-1]
    assert last["relative"]["tau_1"] <= 0.02
    assert last["relax"][0]["tau"] == pytest.approx(1413.0, rel=0.06)  # 3 s.e.
    assert main(["analyze", str(run)]) == 0
    summary = capsys.readouterr().out
    assert f"adaptive hold ended on its target (every tau to 2 %, 1 term(s) resolved) after " \
           f"{hold['held_s']:.0f} s of at most 3000 s" in summary
    report = (run / "analysis" / "report.html").read_text()
    assert "Live fit during the hold" in report


def test_min_hold_above_hold_is_one_line_exit_2(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(ADAPTIVE.format(hold="100 s", min_hold="200 s"))
    assert main(["plan", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "min_hold" in err[0] and "at most hold (100 s)" in err[0]
