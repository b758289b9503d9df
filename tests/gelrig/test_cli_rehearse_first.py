"""Issue 27: the sample is an input, `gelrig run` rehearses first, `gelrig plan` shows the
parameters each step uses and says each error once. Through the whole simulated rig."""

from pathlib import Path

import pytest

import gelrig
import gelrig.factory
from gelrig.cli import main
from gelrig.instrument.core.store import RunDirectory

SCRIPT = '''import gelrig


@gelrig.protocol(rig="compression", name="twelve")
def twelve(run: gelrig.Run, strain: float = 0.04, second: float = 0.04) -> None:
    run.step("compression_contact_search", name="contact search", confirm=0)
    held = run.step("ramp_hold", name="hold", strain=strain, hold="10 s", rate="100 Hz",
                    terms=1)
    run.log(f"G_e {held.fits[0]['G_e']:.0f} Pa")  # a script reading its fit
    if second != strain:
        run.step("ramp_hold", name="deeper", strain=second, hold="10 s", rate="100 Hz",
                 terms=1)
'''


@pytest.fixture
def script(tmp_path) -> Path:
    path = tmp_path / "twelve.py"
    path.write_text(SCRIPT)
    return path


@pytest.fixture
def never_connects(monkeypatch):
    """The rig (its instruments) is never built: what `gelrig run` refuses before it
    connects leaves the stage where it was, for it was never opened."""
    built = []
    original = gelrig.factory.build_rig

    def build_rig(*args, **kwargs):
        if kwargs.get("in_process"):  # the twin: every instrument a simulator in-process
            return original(*args, **kwargs)
        built.append(args)
        raise AssertionError("the instruments were opened")

    monkeypatch.setattr(gelrig.factory, "build_rig", build_rig)
    return built


def one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_12_mm_sample_gives_a_4_percent_depth_of_0_48_mm(tmp_path, script, capsys):
    out = tmp_path / "run"
    assert main(["run", str(script), "--sample-diameter", "12 mm", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "rehearsal passed in" in printed and "Sample:   sample: diameter 12 mm" in printed
    meta = RunDirectory(out).read_metadata()
    assert meta["sample"] == {"diameter": pytest.approx(12e-3)}
    hold = meta["steps"][1]
    assert hold["params"]["diameter"] == pytest.approx(12e-3)
    assert hold["results"]["depth_m"] == pytest.approx(0.48e-3)  # not 0.745 mm (18.63 mm)
    assert hold["results"]["measured_depth_m"] == pytest.approx(0.48e-3, rel=0.02)


def test_without_a_diameter_it_is_refused_before_motion(tmp_path, script, capsys,
                                                         never_connects):
    out = tmp_path / "runs" / "run"
    assert main(["run", str(script), "--out", str(out)]) == 2
    line = one_line(capsys)
    assert line.startswith("gelrig run: step 1 (hold): diameter = \"missing\"")
    assert "--sample-diameter" in line and line.endswith("refused before anything moves")
    assert not (tmp_path / "runs").exists() and never_connects == []


def test_a_later_step_past_a_limit_is_refused_before_the_contact_search(
        tmp_path, script, capsys, never_connects):
    out = tmp_path / "run"
    code = main(["run", str(script), "--sample-diameter", "12 mm", "--param", "second=0.25",
                 "--out", str(out)])
    assert code == 2
    line = one_line(capsys)
    assert "step 2 (deeper): depth 3.0000 mm beyond the overlap limit 2.5 mm" in line
    assert not out.exists() and never_connects == []  # no contact search ran for real


def test_no_rehearse_runs_straight_away(tmp_path, script, capsys):
    out = tmp_path / "run"
    assert main(["run", str(script), "--sample-diameter", "12 mm", "--no-rehearse",
                 "--out", str(out)]) == 0
    assert "rehearsing" not in capsys.readouterr().out


@pytest.mark.parametrize(("args", "field"), [
    (["--param", "strains=[0.1]"], "strains"),  # unknown
    (["--sample-diameter", "12 s"], "--sample-diameter"),
])
def test_bad_input_is_one_line_exit_2_no_folder(tmp_path, script, capsys, args, field,
                                                never_connects):
    out = tmp_path / "run"
    assert main(["run", str(script), *args, "--out", str(out)]) == 2
    assert field in one_line(capsys)
    assert not out.exists()


def test_a_missing_script_parameter_is_one_line(tmp_path, capsys, never_connects):
    path = tmp_path / "needs.py"
    path.write_text(SCRIPT.replace("strain: float = 0.04,", "strain: float,"))
    assert main(["run", str(path), "--sample-diameter", "12 mm",
                 "--out", str(tmp_path / "run")]) == 2
    line = one_line(capsys)
    assert 'script parameter = "strain"' in line and "--param strain=VALUE" in line
    assert "TypeError" not in line and not (tmp_path / "run").exists()


def test_a_config_error_in_the_script_is_refused_exit_2(tmp_path, capsys, never_connects):
    path = tmp_path / "checks.py"
    path.write_text(SCRIPT.replace(
        "    run.step(\"compression_contact_search\"",
        "    if strain > 0.1:\n        raise gelrig.ConfigError('strain', strain, 'at most 0.1')"
        "\n    run.step(\"compression_contact_search\""))
    assert main(["run", str(path), "--sample-diameter", "12 mm", "--param", "strain=0.2",
                 "--out", str(tmp_path / "run")]) == 2
    line = one_line(capsys)
    assert "strain = 0.2: at most 0.1 (at checks.py:" in line
    assert not (tmp_path / "run").exists()


def test_plan_prints_the_parameters_each_step_uses(script, capsys):
    assert main(["plan", str(script), "--sample-diameter", "12 mm"]) == 0
    out = capsys.readouterr().out
    uses = [line for line in out.splitlines() if line.startswith("   uses ")]
    assert len(uses) == 2
    assert "diameter = 12 mm (sample)" in uses[1] and "strain = 0.04" in uses[1]
    assert "strain_rate = 0.002 1/s (default)" in uses[1] and "hold = 10 s" in uses[1]
    assert "speed = 0.3 mm/s (default)" in uses[0]


def test_plan_of_a_protocol_file_prints_the_parameters(capsys):
    assert main(["plan", "paper:compression", "--sample-diameter", "12 mm"]) == 0
    out = capsys.readouterr().out
    assert "diameter = 12 mm (sample)" in out and "strain = 0.06," in out
    assert "ramp 0.7200 mm (6 % of 12 mm)" in out


def test_plan_says_the_users_error_once_in_one_line(tmp_path, capsys):
    path = tmp_path / "mine.py"
    path.write_text(SCRIPT.replace("held.fits[0]['G_e']", "held.fits[3]['G_e']"))
    assert main(["plan", str(path), "--sample-diameter", "12 mm"]) == 2
    captured = capsys.readouterr()
    line = one_line_of(captured.err)
    assert line.startswith("gelrig plan: the script raised IndexError: list index out of "
                           "range (at mine.py:")
    assert "Traceback" not in captured.out + captured.err
    assert "IndexError" not in captured.out  # said once, on stderr


def one_line_of(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_rehearsal_fits_have_the_runs_fields(script):
    report = gelrig.rehearse(script, sample={"diameter": "12 mm"})
    assert report.ok, report.failure()
    fits = report.steps[1].results["fits"]
    assert fits and "G_e" in fits[0] and "relax" in fits[0] and "rehearsal" in fits[0]
    assert fits[0]["G_e"] > 0


def test_run_names_the_scripts_own_exception_found_by_the_rehearsal(tmp_path, capsys,
                                                                     never_connects):
    path = tmp_path / "mine.py"
    path.write_text(SCRIPT.replace("held.fits[0]['G_e']", "held.fits[3]['G_e']"))
    assert main(["run", str(path), "--sample-diameter", "12 mm",
                 "--out", str(tmp_path / "run")]) == 2
    line = one_line(capsys)
    assert line.startswith("gelrig run: the script raised IndexError: list index out of range "
                           "(at mine.py:")
    assert "nothing was connected or moved" in line and "gelrig-rehearsal.log" in line
    assert not (tmp_path / "run").exists()
