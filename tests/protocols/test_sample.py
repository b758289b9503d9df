"""The run's sample (issue 27, item 1): steps take their sizes from it, none is a default."""

from pathlib import Path

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.resolve import resolve_procedure
from gelrig.protocols.sample import Sample, resolve_sample, sample_from_options
from gelrig.protocols.spec import load_protocol, paper_protocol, parse_protocol

ROOT = Path(__file__).resolve().parents[2]


def table(sample=None, **hold):
    out = {"protocol": {"name": "p", "rig": "compression"},
           "step": [{"kind": "compression_contact_search"},
                    {"kind": "ramp_hold", "strain": 0.04, **hold}]}
    if sample is not None:
        out["sample"] = sample
    return out


def test_ramp_hold_takes_the_samples_diameter():
    spec = parse_protocol(table({"name": "A3", "diameter": "12 mm"}))
    params = spec.steps[1].params
    assert params.diameter == pytest.approx(12e-3)
    assert params.depth == pytest.approx(0.48e-3)  # 4 % of 12 mm, not of the paper's sphere
    assert spec.sample == Sample("A3", 12e-3)


def test_no_diameter_anywhere_is_refused_naming_the_field():
    with pytest.raises(ConfigError) as error:
        parse_protocol(table(), "p.toml")
    text = str(error.value)
    assert "[step[1]] diameter" in text and "missing" in text and "--sample-diameter" in text
    assert "\n" not in text and "18.63" not in text


def test_a_step_diameter_other_than_the_samples_is_refused():
    with pytest.raises(ConfigError, match=r'diameter = "18.63 mm": differs from the sample'):
        parse_protocol(table({"diameter": "12 mm"}, diameter="18.63 mm"))
    same = parse_protocol(table({"diameter": "12 mm"}, diameter="0.012 m"))
    assert same.steps[1].params.diameter == pytest.approx(12e-3)


def test_a_given_sample_replaces_the_files():
    paper = resolve_procedure("paper:compression")
    assert paper.steps[1].params.diameter == pytest.approx(18.63e-3)
    mine = resolve_procedure("paper:compression", sample={"diameter": "12 mm"})
    assert mine.steps[1].params.diameter == pytest.approx(12e-3)
    assert mine.table["sample"] == {"diameter": pytest.approx(12e-3)}


@pytest.mark.parametrize("bad", [{"diameter": "-1 mm"}, {"diameter": "12 s"}, {"radius": "1"}])
def test_a_bad_sample_names_the_field(bad):
    with pytest.raises(ConfigError, match=r"\[sample\] (diameter|radius)"):
        parse_protocol(table(bad))


def test_sample_options_and_files(tmp_path):
    assert sample_from_options(None, None) is None
    assert sample_from_options(None, "12 mm") == Sample(diameter=12e-3)
    file = tmp_path / "a3.toml"
    file.write_text('[sample]\nname = "A3"\ndiameter = "12 mm"\nmaterial = "Sylgard 184"\n')
    assert resolve_sample(file) == Sample("A3", 12e-3, material="Sylgard 184")
    assert sample_from_options(str(file), "11 mm").diameter == pytest.approx(11e-3)
    with pytest.raises(ConfigError, match=r'--sample-diameter = "twelve"'):
        sample_from_options(None, "twelve")
    (tmp_path / "none.toml").write_text('name = "x"\n')
    with pytest.raises(ConfigError, match=r"\[sample\]"):
        resolve_sample(tmp_path / "none.toml")


def test_paper_protocols_and_example_files_state_their_sample():
    compression = load_protocol(paper_protocol("compression"))
    assert compression.sample.diameter == pytest.approx(18.63e-3)
    shear = load_protocol(paper_protocol("shear"))
    assert (shear.sample.r1, shear.sample.r2) == pytest.approx((9.2e-3, 9.96e-3))
    for path in (ROOT / "examples").glob("*.toml"):
        assert load_protocol(path).sample is not None, path


def test_no_step_kind_defaults_a_size_to_the_papers():
    from gelrig.instrument.physics import paper
    from gelrig.protocols.steps import KINDS

    sizes = {paper.DIAMETER_COMPRESSION, paper.R_COMPRESSION, paper.R1_SHEAR, paper.R2_SHEAR}
    for kind, definition in KINDS.items():
        for spec in definition.Params.specs().values():
            assert getattr(spec, "default", None) not in sizes, (kind, spec.key)


def test_a_scripts_missing_parameter_is_a_config_error(tmp_path):
    file = tmp_path / "needs.py"
    file.write_text("import gelrig\n\n@gelrig.protocol(rig='compression')\n"
                    "def needs(run, strain):\n    pass\n")
    with pytest.raises(ConfigError) as error:
        resolve_procedure(file)
    assert "strain" in str(error.value) and "--param strain=VALUE" in str(error.value)
    assert resolve_procedure(file, {"strain": 0.04}).params == {"strain": 0.04}


def test_the_analysis_takes_the_shear_radii_from_the_runs_sample(caplog):
    from gelrig.analyze_run import _radii

    meta = {"sample": {"r1": 5e-3, "r2": 6e-3}}
    assert _radii(meta, None, None) == (5e-3, 6e-3)
    assert _radii(meta, 4e-3, None) == (4e-3, 6e-3)  # given wins
    table = {"protocol": {"sample": {"r1": 7e-3, "r2": 8e-3}}}
    assert _radii(table, None, None) == (7e-3, 8e-3)
    written = {"protocol": {"sample": {"r1": "9.2 mm", "r2": "9.96 mm"}}}  # as in the file
    assert _radii(written, None, None) == pytest.approx((9.2e-3, 9.96e-3))
    assert "not given" not in caplog.text
    assert _radii({}, None, None) == pytest.approx((9.2e-3, 9.96e-3))  # an old run: said
    assert "r1 not given and not in run.json's sample" in caplog.text
