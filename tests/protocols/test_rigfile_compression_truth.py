"""The compression rig file's hidden truth: the unloading model ([simulator] unloading)."""

import re
from pathlib import Path

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.rigfile import CompressionRigSpec, default_rig, load_rig, parse_rig

MDR_RIG = Path(__file__).resolve().parents[2] / "examples" / "rigs" / "compression_mdr.toml"


def compression(**simulator):
    table = {"rig": {"kind": "compression"}, "stage": {"transport": "simulator"},
             "force": {"transport": "simulator"}, "simulator": simulator}
    spec = parse_rig(table, "rig.toml")
    assert isinstance(spec, CompressionRigSpec)
    return spec.simulator


def test_unloading_defaults_to_the_cutoff_and_is_read():
    assert compression().unloading == "cutoff"
    assert compression(unloading="mdr").unloading == "mdr"


def test_a_bad_unloading_model_is_one_line():
    with pytest.raises(ConfigError, match=re.escape(
            'rig.toml: [simulator] unloading = "ting": allowed: cutoff, mdr')):
        compression(unloading="ting")


def test_the_example_mdr_rig_is_the_built_in_rig_but_for_unloading():
    mdr, built_in = load_rig(MDR_RIG), load_rig(default_rig("compression"))
    assert isinstance(mdr, CompressionRigSpec) and isinstance(built_in, CompressionRigSpec)
    assert (mdr.simulator.unloading, built_in.simulator.unloading) == ("mdr", "cutoff")
    assert (mdr.stage, mdr.force, mdr.limits) == (built_in.stage, built_in.force,
                                                  built_in.limits)
    assert mdr.simulator.material == built_in.simulator.material


# The instruments' hidden facts (issue 30): counts_per_mm, rated_output, direction, noise.

def test_the_hidden_facts_default_to_the_rig_files_belief():
    truth = compression()
    assert (truth.counts_per_mm, truth.rated_output, truth.direction) == (None, None, None)


def test_the_hidden_facts_are_read_in_si():
    truth = compression(counts_per_mm=34304, rated_output="2.06 mV/V", direction=-1,
                        noise="0.35 mN")
    assert truth.counts_per_mm == 34304
    assert truth.rated_output == pytest.approx(2.06e-3)
    assert truth.direction == -1
    assert truth.noise == pytest.approx(0.35e-3)


@pytest.mark.parametrize(("key", "value", "message"), [
    ("direction", 0, "rig.toml: [simulator] direction = 0: allowed: +1 (forward is larger "
                     "counts) or -1 (forward is smaller counts)"),
    ("direction", 2, "rig.toml: [simulator] direction = 2: "),
    ("counts_per_mm", -5, "rig.toml: [simulator] counts_per_mm = -5: "),
    ("rated_output", "20 mV/V", 'rig.toml: [simulator] rated_output = "20 mV/V": '),
    ("rated_output", "2 mm", 'rig.toml: [simulator] rated_output = "2 mm": '),
])
def test_a_bad_hidden_fact_is_one_line_naming_field_value_and_allowed(key, value, message):
    with pytest.raises(ConfigError) as err:
        compression(**{key: value})
    text = str(err.value)
    assert text.startswith(message) and "\n" not in text
    assert "allowed" in text or "must" in text or "in (" in text or "[" in text


def _with_chain_noise(**simulator):
    table = {"rig": {"kind": "compression"}, "stage": {"transport": "simulator"},
             "force": {"transport": "simulator", "chain": {"noise": "0.35 mN"}},
             "simulator": simulator}
    spec = parse_rig(table, "rig.toml")
    assert isinstance(spec, CompressionRigSpec)
    return spec


def test_the_noise_measured_at_bring_up_is_the_twins():
    spec = _with_chain_noise()
    assert spec.force.chain.noise == pytest.approx(0.35e-3)
    assert spec.simulator.noise == pytest.approx(0.35e-3)


def test_a_simulator_noise_given_stays_the_truth():
    assert _with_chain_noise(noise="0.1 mN").simulator.noise == pytest.approx(0.1e-3)
    assert compression().noise == pytest.approx(0.2e-3)  # no measurement: the default
