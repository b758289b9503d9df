"""The shear rig file's hidden truth: fresh contact by default, carry_history, unloading,
and the anisotropic F_v material (relax_vertical)."""

import re

import pytest

from instrument.contact import Material
from instrument.errors import ConfigError
from protocols.rigfile import ShearRigSpec, parse_rig


def shear(**simulator):
    table = {"rig": {"kind": "shear"}, "rheometer": {"transport": "simulator"},
             "simulator": simulator}
    spec = parse_rig(table, "rig.toml")
    assert isinstance(spec, ShearRigSpec)
    return spec.simulator


def test_defaults_are_a_fresh_cutoff_contact_with_one_material():
    truth = shear()
    assert (truth.carry_history, truth.unloading, truth.material_vertical) == (
        False, "cutoff", None)


def test_options_are_read():
    truth = shear(g_e="4 kPa", relax=[["20 kPa", "2000 s"]],
                  relax_vertical=[["16 kPa", "2000 s"]], carry_history=True, unloading="mdr")
    assert truth.carry_history is True and truth.unloading == "mdr"
    assert truth.material == Material.of(4e3, [(2e4, 2000.0)])
    assert truth.material_vertical == Material.of(4e3, [(1.6e4, 2000.0)])


@pytest.mark.parametrize(("simulator", "message"), [
    ({"carry_history": "yes"},
     re.escape('rig.toml: [simulator] carry_history = "yes": allowed: true or false')),
    ({"unloading": "ting"},
     re.escape('rig.toml: [simulator] unloading = "ting": allowed: cutoff, mdr')),
    ({"relax_vertical": [["16 kPa", "2000 s"]]}, "relax_vertical .* needs g_e"),
    ({"g_e": "4 kPa", "relax_vertical": [["16 kPa"]]}, r"relax_vertical\[0\]"),
])
def test_bad_options_are_one_line(simulator, message):
    with pytest.raises(ConfigError, match=message):
        shear(**simulator)
