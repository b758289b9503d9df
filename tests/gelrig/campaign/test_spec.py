"""The campaign file: grids expanded into members with stable ids; every bad value one line."""

from __future__ import annotations

import copy

import pytest

from gelrig.campaign.spec import load_campaign, parse_campaign
from gelrig.cli import main
from gelrig.instrument.core.errors import ConfigError
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
    ({"analysis": {"anisotropic": "yes"}}, "[analysis] anisotropic = \"yes\": allowed: true or"),
    ({"analysis": {"terms": 3}}, "[analysis] terms = 3: allowed an integer in [1, 2]"),
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
    run.step("ramp_hold", diameter="18.63 mm", hold=hold, strain=strain, rate="100 Hz", terms=1)
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


def test_a_truth_drawn_from_a_distribution_per_member(tmp_path):
    from gelrig.campaign.member import run_member
    from gelrig.protocols.rigfile import parse_rig

    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=4,
                      simulator='g_e = { uniform = ["6 kPa", "8 kPa"] }\n'
                                'relax = [[{ loguniform = ["300 Pa", "900 Pa"] }, "1413 s"]]\n'
                                'noise = ["0.2 mN", "0.4 mN"]')
    spec = load_campaign(path)
    assert len(spec.members) == 8
    drawn = [parse_rig(m.rig_table, "m").simulator.material for m in spec.members]
    g_e = [mat.g_e for mat in drawn]
    g_1 = [mat.relax[0].g for mat in drawn]
    assert all(6000 <= g <= 8000 for g in g_e) and all(300 <= g <= 900 for g in g_1)
    assert len(set(g_e[:4])) == 4  # a new draw for each seed...
    assert g_e[:4] == g_e[4:]  # ...and the same draws in each noise variant (same seeds)
    assert [m.member_id for m in load_campaign(path).members] == \
        [m.member_id for m in spec.members]  # drawn from the seeds: the same every time
    assert len({m.truth["g_e"] == {"uniform": ["6 kPa", "8 kPa"]} for m in spec.members}) == 1
    row = run_member(spec.members[0])
    assert row["status"] == "ok", row["error"]
    assert (row["truth.G_e"], row["truth.G_1"]) == pytest.approx((g_e[0], g_1[0]))
    # a 60 s hold pins the instantaneous modulus, not its split into G_e and G_1
    assert row["fit.G_e"] + row["fit.G_1"] == pytest.approx(g_e[0] + g_1[0], rel=0.02)


@pytest.mark.parametrize(("value", "expected"), [
    ('{ uniform = ["8 kPa", "6 kPa"] }', "with low < high"),
    ('{ gauss = [1, 2] }', "one of { uniform = [low, high] }"),
    ('{ uniform = ["6 kPa", "8000 Pa"] }', "both numbers of uniform in one unit"),
    ('{ normal = ["7 kPa", "0 kPa"] }', "sd > 0"),
    ('{ normal = ["7 kPa", "20 kPa"] }', "narrow the distribution"),
])
def test_a_bad_distribution_is_one_line(tmp_path, value, expected):
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=20, simulator=f"g_e = {value}")
    with pytest.raises(ConfigError) as info:
        load_campaign(path)
    message = str(info.value)
    assert "[simulator] g_e" in message and expected in message and "\n" not in message


def test_the_analysis_table_is_the_ladder_fits_declarations():
    """[analysis] shares the fit's fields (one declaration, one default)."""
    from gelrig.campaign.spec import Analysis
    from gelrig.instrument.analysis.fit_setup import FitSetup

    fit, analysis = FitSetup.specs(), Analysis.specs()
    for name in ("terms", "anisotropic", "fit_geometry"):
        assert analysis[name] is fit[name]
    assert analysis["unloading"].choices == (*fit["unloading"].choices, "truth")
    default = Analysis()
    assert (default.terms, default.anisotropic, default.fit_geometry) == (
        FitSetup().terms, FitSetup().anisotropic, FitSetup().fit_geometry)
    assert type(Analysis.from_table({"terms": 2}).terms) is int


def test_a_grid_beyond_the_member_bound_is_refused_by_arithmetic(tmp_path, capsys):
    """10^11 members (was: 5.3 GB and no output): refused from the axes' lengths alone,
    before any member or grid value is made."""
    import time

    axis = "[" + ", ".join(f'"{k} mN"' for k in range(1, 11)) + "]"
    path = tmp_path / "huge.toml"
    path.write_text(tiny.COMPRESSION.format(replicates=10, simulator=f"noise = {axis}")
                    .replace('"step[1].hold" = "60 s"', "\n".join(
                        f'"step[1].{k}" = [{", ".join(str(v / 10) for v in range(1, 11))}]'
                        for k in ("strain", "strain_rate", "terms", "approach", "retract",
                                  "tare_time", "until", "min_hold", "diameter"))))
    start = time.monotonic()
    assert main(["campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert time.monotonic() - start < 30
    assert len(err.splitlines()) == 1, err
    assert f'{path}: members = "100,000,000,000": at most 100,000 per campaign' in err
    assert "10 ([simulator] noise) x 10 ([params] step[1].strain)" in err
    assert not (tmp_path / "out").exists()


def test_a_grid_whose_largest_member_is_beyond_the_run_bounds_is_refused(tmp_path, capsys):
    path = tmp_path / "long.toml"
    path.write_text(tiny.COMPRESSION.format(replicates=2, simulator="")
                    .replace('"step[1].hold" = "60 s"', '"step[1].hold" = ["60 s", "604800 s"]')
                    .replace('"step[1].rate" = "100 Hz"',
                             '"step[1].rate" = ["100 Hz", "20000 Hz"]'))
    assert main(["campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f'{path}: [params] samples per run = "12,09' in err
    assert "step[1] (ramp and hold) records" in err and "(the grid's largest member)" in err


def test_a_protocol_file_with_repeat_is_refused_by_a_campaign(tmp_path):
    """[params] address a file's step tables by index: a repeated table is several steps."""
    (tmp_path / "p.toml").write_text(
        '[protocol]\nname = "p"\nrig = "compression"\n[sample]\ndiameter = "18.63 mm"\n'
        '[[step]]\nkind = "wait"\nname = "settle"\nduration = "5 s"\nrepeat = 2\n')
    path = tiny.write(tmp_path, tiny.COMPRESSION.replace('"paper:compression"', '"p.toml"')
                      .split("[params]")[0], replicates=1)
    with pytest.raises(ConfigError, match=r'protocol = "p\.toml": uses repeat'):
        load_campaign(path)
