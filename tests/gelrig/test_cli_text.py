"""`gelrig run` on the simulated rig with hostile text, and the one exit-code rule, through
the real command line (a subprocess: exit code and stderr as a person sees them).

Text is text: a step named like rich markup, an exception whose text holds ``[/...]``, a cap's
``[limits]`` table name all reach stderr as written, and the run's exit code follows run.json.
One exit-code rule: a protocol the rig's caps refuse before anything moves exits 2 with one
line on stderr and leaves no run folder (``run``), or leaves the run as it was (``resume``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gelrig.protocols.rigfile import default_rig

HOSTILE_NAMES = ("[/x] hold", "[bold]probe :warning: [limits]")

PROTOCOL = """
[protocol]
name = "hostile [/names]"
rig = "compression"

[[step]]
kind = "compression_contact_search"
name = "{search}"
confirm = 0

[[step]]
kind = "ramp_hold"
diameter = "18.63 mm"
name = "{hold}"
hold = "5 s"
rate = "100 Hz"
terms = 1
"""

SCRIPT = '''
from dataclasses import dataclass
from typing import ClassVar

import gelrig


@dataclass(frozen=True)
class BoomParams(gelrig.StepParams):
    pass


@dataclass(frozen=True)
class BoomResult(gelrig.StepResult):
    pass


@gelrig.register_step
class Boom(gelrig.StepDefinition):
    kind: ClassVar[str] = "test_text_boom"
    rig = gelrig.CompressionRig
    Params, Result = BoomParams, BoomResult
    columns: ClassVar[dict[str, str]] = {}

    def plan(self, params, limits):
        return gelrig.StepPlan(0.0, 0.0, ["boom"])

    def run(self, ctx, params):
        raise ValueError("[/y] step code broke at [limits] max_force")  # STEP LINE


@gelrig.protocol(rig="compression", name="hostile")
def hostile(run: gelrig.Run, where="between") -> None:
    run.step("compression_contact_search", name="[/x] search", confirm=0)
    if where == "between":
        raise RuntimeError("[/x] the script broke [bold]here")  # SCRIPT LINE
    if where == "step":
        run.step("test_text_boom", name="[/z] boom")
    if where == "deep":
        run.step("ramp_hold", diameter="18.63 mm", name="deep [/x]", strain=0.3, hold="5 s",
                 rate="100 Hz")
'''


def gelrig(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "gelrig.cli", *args], cwd=cwd, text=True,
                          capture_output=True, timeout=240,
                          env={**os.environ, "COLUMNS": "200"})


def no_traceback(err: str) -> None:
    assert "Traceback" not in err and "MarkupError" not in err, err


def status(run: Path) -> str:
    return str(json.loads((run / "run.json").read_text())["status"])


@pytest.mark.slow
def test_a_step_named_like_markup_runs_and_shows_its_name(tmp_path: Path) -> None:
    search, hold = HOSTILE_NAMES
    (tmp_path / "p.toml").write_text(PROTOCOL.format(search=search, hold=hold))
    done = gelrig("run", "p.toml", "--out", "run", cwd=tmp_path)
    no_traceback(done.stderr)
    assert done.returncode == 0, done.stderr
    assert status(tmp_path / "run") == "completed"
    assert f"0: {search}" in done.stderr and f"1: {hold}" in done.stderr
    assert "hostile [/names]" in done.stdout


def fault_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("FAULT")]
    assert len(lines) == 1, err
    return lines[0]


def line_of(marker: str) -> int:
    return next(i for i, text in enumerate(SCRIPT.splitlines(), 1) if marker in text)


@pytest.mark.slow
@pytest.mark.parametrize(("where", "expected"), [
    ("between", "FAULT RuntimeError: [/x] the script broke [bold]here (at hostile.py:{script})"),
    ("step", "FAULT ValueError: [/y] step code broke at [limits] max_force (at hostile.py:{step})"),
    ("deep", "FAULT LimitError: step 1 (deep [/x]): depth "),
])
def test_the_fault_line_shows_the_exception_as_written_with_its_origin(
        tmp_path: Path, where: str, expected: str) -> None:
    (tmp_path / "hostile.py").write_text(SCRIPT)
    done = gelrig("run", "hostile.py", "--param", f'where="{where}"', "--no-rehearse",
                  "--out", "run",
                  cwd=tmp_path)
    no_traceback(done.stderr)
    # a step the caps refuse after the search moved: refused (exit 2), the search's data kept
    assert done.returncode == (2 if where == "deep" else 1), done.stderr
    assert status(tmp_path / "run") == ("refused" if where == "deep" else "failed")
    line = fault_line(done.stderr)
    assert line.startswith(expected.format(script=line_of("SCRIPT LINE"),
                                           step=line_of("STEP LINE"))), line
    if where == "deep":  # a cap refused it at run time: the rig file's table name kept
        assert "([limits] max_overlap); refused before it moved" in line
    assert line.endswith(f"details: {Path('run') / 'gelrig.log'}")


def slow_rig(tmp_path: Path) -> Path:
    text = default_rig("compression").read_text()
    assert 'max_velocity = "2.3 mm/s"' in text
    path = tmp_path / "slow.toml"
    path.write_text(text.replace('max_velocity = "2.3 mm/s"', 'max_velocity = "1 mm/s"'))
    return path


FAST = """
[protocol]
name = "too fast"
rig = "compression"

[[step]]
kind = "compression_contact_search"
name = "probe"
confirm = 0
speed = "1.31 mm/s"
"""

REFUSED = ("step 0 (probe): speed 1.31 mm/s above the stage's max_velocity 1 mm/s "
           "([stage] max_velocity); refused before anything moves")


@pytest.mark.slow
def test_a_run_the_caps_refuse_exits_2_with_one_line_and_no_run_folder(tmp_path: Path
                                                                        ) -> None:
    (tmp_path / "fast.toml").write_text(FAST)
    done = gelrig("run", "fast.toml", "--rig", str(slow_rig(tmp_path)), "--out", "run",
                  cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [f"gelrig run: {REFUSED}"]
    assert not (tmp_path / "run").exists()
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
def test_a_resume_the_caps_refuse_exits_2_and_leaves_the_run_as_it_was(tmp_path: Path
                                                                        ) -> None:
    from gelrig.protocols.host import create_run
    from gelrig.protocols.resolve import resolve_procedure, resolve_rig

    (tmp_path / "fast.toml").write_text(FAST)
    procedure = resolve_procedure(tmp_path / "fast.toml")  # a run of it that ended short
    run = create_run(procedure, resolve_rig(slow_rig(tmp_path), procedure), "virtual",
                     tmp_path / "run")
    run.update(status="failed")
    before = (tmp_path / "run" / "run.json").read_text()
    done = gelrig("resume", "run", "--out", "copy", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [f"gelrig resume: {REFUSED}"]
    assert (tmp_path / "run" / "run.json").read_text() == before
    assert not (tmp_path / "copy").exists()
