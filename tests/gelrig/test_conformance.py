"""gelrig check: the same checks against the twin (here) as against the instruments."""

from __future__ import annotations

from gelrig.cli import main
from gelrig.protocols.rigfile import default_rig


def test_the_built_in_twins_pass_every_check(capsys):
    assert main(["check", str(default_rig("compression")), "--motion"]) == 0
    out = capsys.readouterr().out
    assert "8 of 8 checks passed" in out and "FAIL" not in out
    assert main(["check", str(default_rig("shear"))]) == 0
    assert "4 of 4 checks passed" in capsys.readouterr().out


def test_a_direction_convention_the_controller_does_not_follow_fails(tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    rig.write_text(default_rig("compression").read_text().replace(
        "seed = 1", "seed = 1\ndirection = 1"))  # the controller's forward is larger counts
    assert main(["check", str(rig), "--motion"]) == 1
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if "small move and back" in ln)
    assert line.strip().startswith("FAIL") and "LACKS the forward_is_negative" in line
    assert "7 of 8 checks passed" in out


def test_without_motion_nothing_moves_and_a_bad_rig_is_exit_2(tmp_path, capsys):
    assert main(["check", str(default_rig("compression"))]) == 0
    assert "small move" not in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text("[rig]\nkind = \"drill\"\n")
    assert main(["check", str(bad)]) == 2
    assert "\n" not in capsys.readouterr().err.strip()
