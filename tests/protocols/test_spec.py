"""Protocol files: the paper's two load and plan; bad files get one precise error each."""

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.rig import CompressionLimits, ShearLimits
from gelrig.protocols.spec import load_protocol, paper_protocol, parse_protocol


def test_paper_protocols_load_and_plan():
    comp = load_protocol(paper_protocol("compression"))
    assert comp.rig == "compression"
    assert [s.kind for s in comp.steps] == ["compression_contact_search", "ramp_hold"]
    hold = comp.steps[1]
    assert hold.params.strain == 0.06 and hold.params.hold == 3000.0
    plan = hold.definition.plan(hold.params, CompressionLimits())
    assert plan.duration == pytest.approx(3000 + (1.1178e-3 + 1e-4) / 3.726e-5 + 4.0, rel=1e-3)
    assert all(c.ok for c in plan.checks)
    shear = load_protocol(paper_protocol("shear"))
    ladder = shear.steps[1]
    assert ladder.params.speeds == (2.38e-5, 4.75e-5, 1.19e-4, 2.37e-4)
    lplan = ladder.definition.plan(ladder.params, ShearLimits())
    legs = sum(2 * 16e-3 / v + 120 for v in ladder.params.speeds)
    assert lplan.duration == pytest.approx(5 * legs)
    assert any("672 s" in line for line in lplan.lines)


def test_plan_flags_a_limit_violation():
    table = {"protocol": {"name": "deep", "rig": "shear"},
             "step": [{"kind": "speed_ladder", "first_overlap": "1.1 mm"}]}
    step = parse_protocol(table).steps[0]
    checks = step.definition.plan(step.params, ShearLimits()).checks
    assert not checks[0].ok and "1.50 mm" in checks[0].message


GOOD = {"protocol": {"name": "p", "rig": "compression"},
        "step": [{"kind": "ramp_hold", "diameter": "18.63 mm", "hold": "10 s"}]}


@pytest.mark.parametrize("mutate,field,needle", [
    (lambda t: t.pop("protocol"), "[protocol]", "a [protocol] table"),
    (lambda t: t["protocol"].update(rig="bench"), "[protocol] rig", "compression, shear"),
    (lambda t: t["protocol"].update(speed=3), "[protocol] speed", "unknown field"),
    (lambda t: t.pop("step"), "[[step]]", "at least one"),
    (lambda t: t["step"][0].update(kind="hover"), "[step[0]] kind", "allowed for a compression"),
    (lambda t: t["step"][0].update(kind="speed_ladder"), "[step[0]] kind", "shear rig"),
    (lambda t: t["step"][0].update(hold="-3 s"), "[step[0]] hold", "[0, 604800] s"),
    (lambda t: t["step"][0].update(hold="3 mm"), "[step[0]] hold", "dimension"),
    (lambda t: t["step"][0].update(strain=0.9), "[step[0]] strain", "(0, 0.3]"),
    (lambda t: t["step"][0].update(rate="10 Hz"), "[step[0]] rate", "[100, 20000] Hz"),
    (lambda t: t["step"][0].update(terms=1.5), "[step[0]] terms", "integer"),
    (lambda t: t["step"][0].update(colour="red"), "[step[0]] colour", "unknown field"),
    (lambda t: t["step"][0].update(hold=True), "[step[0]] hold", "a number"),
])
def test_bad_protocols(mutate, field, needle):
    import copy
    table = copy.deepcopy(GOOD)
    mutate(table)
    with pytest.raises(ConfigError) as err:
        parse_protocol(table, "p.toml")
    assert err.value.field == field
    assert needle in str(err.value) and str(err.value).startswith("p.toml: ")
    assert "\n" not in str(err.value)


def test_bad_speed_list():
    table = {"protocol": {"name": "p", "rig": "shear"},
             "step": [{"kind": "speed_ladder", "speeds": ["1 mm/s", "fast"]}]}
    with pytest.raises(ConfigError, match=r"\[step\[0\]\] speeds\[1\] = \"fast\""):
        parse_protocol(table)


def test_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[protocol\nname=")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_protocol(bad)
    with pytest.raises(ConfigError, match="cannot be read"):
        load_protocol(tmp_path / "none.toml")


def test_ladder_read_period_keeps_the_stream_buffer_from_overflowing():
    table = {"protocol": {"name": "p", "rig": "shear"},
             "step": [{"kind": "speed_ladder", "interval": "0.001 s", "read_period": "10 s"}]}
    with pytest.raises(ConfigError, match=r"\[step\[0\]\] read_period = 10.0: at most 2048"):
        parse_protocol(table)
    table["step"][0]["read_period"] = "2 s"
    assert parse_protocol(table).steps[0].params.read_period == 2.0
