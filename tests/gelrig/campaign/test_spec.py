"""The campaign file: grids expanded into members with stable ids; every bad value one line."""

from __future__ import annotations

import copy

import pytest

from gelrig.campaign.spec import load_campaign, parse_campaign
from gelrig.cli import main
from instrument.errors import ConfigError
from tests.gelrig.campaign import tiny


def test_grids_times_seeds_make_the_members(tmp_path):
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=3,
                      simulator='noise = ["0.1 mN", "0.2 mN"]\nrelax = [[["630 Pa", "1413 s"]],'
                                ' [["300 Pa", "1000 s"]]]')
    spec = load_campaign(path)
    assert len(spec.members) == 2 * 2 * 3
    assert len({m.member_id for m in spec.members}) == len(spec.members)
    assert sorted({m.seed for m in spec.members}) == [1, 2, 3]
    first = spec.members[0]
    assert first.rig_table["simulator"]["seed"] == first.seed
    assert first.rig_table["simulator"]["noise"] == "0.1 mN"
    assert first.protocol_table["step"][1]["hold"] == "60 s"


def test_member_ids_are_stable_and_follow_truth_params_and_seed(tmp_path):
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=2)
    a, b = load_campaign(path), load_campaign(path)
    assert [m.member_id for m in a.members] == [m.member_id for m in b.members]
    table = copy.deepcopy(a.table)
    table["params"]["step[1].hold"] = "61 s"
    changed = parse_campaign(table, "c.toml")
    assert not {m.member_id for m in changed.members} & {m.member_id for m in a.members}
    table = copy.deepcopy(a.table)
    table["campaign"]["first_seed"] = 2  # seeds 2, 3: seed 2 is the same member as before
    shifted = parse_campaign(table, "c.toml")
    assert shifted.members[0].member_id == a.members[1].member_id


def test_a_list_field_takes_a_list_of_lists_as_its_grid(tmp_path):
    path = tiny.write(tmp_path, tiny.SHEAR, replicates=1)
    text = path.read_text().replace('[["2.38e-5 m/s", "2.37e-4 m/s"]]',
                                    '[["2.38e-5 m/s"], ["2.38e-5 m/s", "2.37e-4 m/s"]]')
    path.write_text(text)
    spec = load_campaign(path)
    assert [m.params["step[1].speeds"] for m in spec.members] == [
        ["2.38e-5 m/s"], ["2.38e-5 m/s", "2.37e-4 m/s"]]


@pytest.mark.parametrize(("edit", "expected"), [
    ({"simulator": {"noise": ["0.1 mN", "5 N"]}}, "[simulator] noise = \"5 N\": allowed"),
    ({"simulator": {"seed": 3}}, "[simulator] seed = 3: set by the campaign"),
    ({"simulator": {"colour": "red"}}, "[simulator] colour"),
    ({"params": {"step[1].hold": ["60 s", "-5 s"]}}, "hold = \"-5 s\": allowed"),
    ({"params": {"step[7].hold": "60 s"}}, "[params] step[7].hold"),
    ({"params": {"step[1].colour": 1}}, "unknown field of step[1]"),
    ({"params": {"step[1].hold": []}}, "a non-empty list"),
    ({"campaign": {"protocol": "paper:nope"}}, "[campaign] protocol = \"paper:nope\""),
    ({"campaign": {"protocol": "study.py"}}, "[campaign] protocol = \"study.py\": no such"),
    ({"campaign": {"replicates": 0}}, "[campaign] replicates = 0: allowed"),
    ({"analysis": {"unloading": "glue"}}, "[analysis] unloading = \"glue\": allowed"),
    ({"extra": {}}, "[extra]"),
])
def test_bad_values_name_file_field_value_and_what_is_allowed(tmp_path, edit, expected):
    spec = load_campaign(tiny.write(tmp_path, tiny.COMPRESSION))
    table = copy.deepcopy(spec.table)
    for key, values in edit.items():
        table.setdefault(key, {}).update(values)
    with pytest.raises(ConfigError) as info:
        parse_campaign(table, "c.toml", tmp_path)
    message = str(info.value)
    assert message.startswith("c.toml: ") and "\n" not in message
    assert expected in message


def test_the_cli_reports_a_bad_campaign_in_one_line_with_exit_2(tmp_path, capsys):
    path = tiny.write(tmp_path, tiny.COMPRESSION, simulator="noise = \"5 N\"")
    assert main(["campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"{path}: [simulator] noise = \"5 N\": allowed" in err
    assert not (tmp_path / "out").exists()  # nothing written for a bad file
    for args in (["--workers", "0"], ["--workers", "two"]):
        assert main(["campaign", str(path), *args]) == 2
        assert "--workers" in capsys.readouterr().err


SCRIPT = """
import gelrig


@gelrig.protocol(rig="compression", name="short hold")
def short_hold(run, hold="60 s", strain=0.06):
    run.step("compression_contact_search", start="3 mm", confirm=1)
    run.step("ramp_hold", hold=hold, strain=strain, rate="100 Hz", terms=1)
"""


def test_a_script_protocol_takes_its_parameters_by_name(tmp_path, capsys):
    from gelrig.campaign.member import run_member

    (tmp_path / "study.py").write_text(SCRIPT)
    path = tmp_path / "c.toml"
    path.write_text('[campaign]\nprotocol = "study.py"\nreplicates = 1\n\n'
                    '[params]\nhold = ["20 s", "40 s"]\nstrain = 0.04\n')
    spec = load_campaign(path)
    assert [m.params for m in spec.members] == [{"hold": "20 s", "strain": 0.04},
                                                {"hold": "40 s", "strain": 0.04}]
    assert len({m.member_id for m in spec.members}) == 2
    rows = [run_member(m) for m in spec.members]
    assert [r["status"] for r in rows] == ["ok", "ok"], [r["error"] for r in rows]
    assert [r["param.hold"] for r in rows] == ["20 s", "40 s"]
    assert [round(r["held_s"]) for r in rows] == [20, 40]
    assert all(r["lo.G_e"] < r["fit.G_e"] < r["hi.G_e"] for r in rows)
    path.write_text('[campaign]\nprotocol = "study.py"\n\n[params]\nhld = "20 s"\n')
    assert main(["campaign", str(path)]) == 2
    err = capsys.readouterr().err
    assert "[params] hld" in err and "study.py takes hold, strain" in err
    assert len(err.splitlines()) == 1


def test_analysis_options_left_at_their_defaults_do_not_change_the_ids(tmp_path):
    spec = load_campaign(tiny.write(tmp_path, tiny.COMPRESSION))
    table = copy.deepcopy(spec.table)
    table["analysis"] = {"terms": 1, "model_fit": True}
    same = parse_campaign(table, "c.toml")
    assert [m.member_id for m in same.members] == [m.member_id for m in spec.members]
    table["analysis"] = {"model_fit": False}
    other = parse_campaign(table, "c.toml")
    assert other.members[0].analysis.model_fit is False
    assert other.members[0].member_id != spec.members[0].member_id
