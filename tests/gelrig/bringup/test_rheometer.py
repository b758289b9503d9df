"""MCR 501 bring-up on the twin: the whole command table meets the simulator that serves it."""

from __future__ import annotations

import re
import tomllib

import pytest

from gelrig.bringup import runner
from gelrig.bringup.rheometer import check_reply
from gelrig.cli import main
from gelrig.drivers.mcr501.commands import COMMANDS
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.units import to_si
from gelrig.protocols.rigfile import ShearRigSpec, default_rig, load_rig


def test_every_command_is_sent_and_agrees_with_the_simulator(tmp_path):
    outcome = runner.run(default_rig("shear"), lambda r, c, s: runner.twin_operator(r, c, s),
                         tmp_path / "shear.confirmed.toml")
    table = next(line for line in outcome.findings if line.startswith("command table"))
    assert f"over {len(COMMANDS)} commands of {len(COMMANDS)}; 0 differ" in table
    noise = next(line for line in outcome.findings if line.startswith("torque zero"))
    # the built-in shear rig's truth: 1e-7 N*m and 2e-5 N (standard deviations)
    torque = float(noise.split("noise ")[1].split(" uN*m")[0])
    force = float(noise.split("noise ")[2].split(" mN")[0])
    assert torque == pytest.approx(0.1, rel=0.15) and force == pytest.approx(0.02, rel=0.15)
    # the noise is written to [rheometer] (the twin's from then on)
    assert outcome.written == tmp_path / "shear.confirmed.toml"
    assert {item.key for item in outcome.accepted} == {"torque_noise", "normal_force_noise"}


def _noise(path) -> tuple[float, float]:
    table = tomllib.loads(path.read_text())["rheometer"]
    return (to_si(table["torque_noise"], "N*m", "torque_noise"),
            to_si(table["normal_force_noise"], "N", "normal_force_noise"))


@pytest.mark.slow
def test_the_confirmed_shear_rig_carries_its_noise_and_plans(tmp_path, capsys):
    rig = tmp_path / "shear.toml"
    rig.write_text(default_rig("shear").read_text().replace(
        "seed = 1", 'seed = 1\ntorque_noise = "0.3 uN*m"\nnormal_force_noise = "0.05 mN"'))
    out = tmp_path / "confirmed.toml"
    assert main(["bringup", str(rig), "--operator", "twin", "--out", str(out)]) == 0
    torque, force = _noise(out)
    assert torque == pytest.approx(0.3e-6, rel=0.15) and force == pytest.approx(5e-5, rel=0.15)
    text = out.read_text()
    assert re.search(r"^torque_noise = .*# confirmed: .*\| method: .*\| u: ", text, re.M)
    # the twin of the confirmed file, its [simulator] no longer giving the noise: the
    # [rheometer] table's, measured again by the same routine
    learned = tmp_path / "learned.toml"
    head, sim = text.split("[simulator]")
    sim = "\n".join(ln for ln in sim.splitlines() if "_noise" not in ln)
    learned.write_text(head + "[simulator]" + sim.replace("seed = 1", "seed = 7") + "\n")
    spec = load_rig(learned)
    assert isinstance(spec, ShearRigSpec)
    assert (spec.simulator.torque_noise, spec.simulator.normal_force_noise) == \
        pytest.approx((torque, force), rel=1e-3)
    again = runner.run(learned, lambda r, c, s: runner.twin_operator(
        r, c, s, declines=("rheometer.commands",)), tmp_path / "again.toml")
    assert again.written is not None
    assert _noise(again.written) == pytest.approx((torque, force), rel=0.2)
    capsys.readouterr()
    assert main(["plan", "paper:shear", "--rig", str(out)]) == 0
    assert "rehearsal passed" in capsys.readouterr().out


def test_a_bad_noise_in_the_rheometer_table_is_one_line(tmp_path):
    rig = tmp_path / "shear.toml"
    rig.write_text(default_rig("shear").read_text().replace(
        'arm = "27 mm"', 'arm = "27 mm"\ntorque_noise = "-1 uN*m"'))
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    assert "\n" not in str(err.value) and "torque_noise" in str(err.value)


@pytest.mark.parametrize(("name", "lines", "why"), [
    ("read_gap", [":GAP[3.0000;1]"], "expected :GAP[gap_mm]"),
    ("identify", ["#ERR[10;unknown command]"], "error reply"),
    ("read_stream", ["#DATA[1;0]", ":MEAS[0.1;2]"], "is not :MEAS"),
])
def test_a_reply_unlike_the_table_is_shown(name, lines, why):
    ok, note = check_reply(COMMANDS[name], lines)
    assert not ok and why in note


def test_a_reply_as_the_table_says_passes():
    assert check_reply(COMMANDS["read_gap"], [":GAP[3.0000]"]) == (True, "")
