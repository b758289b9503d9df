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
