"""The shear rig file's hidden truth: fresh contact by default, carry_history, unloading,
and the anisotropic F_v material (relax_vertical)."""

import re

import pytest

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import Material
from gelrig.protocols.rigfile import ShearRigSpec, parse_rig


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


def test_the_noise_of_torque_and_normal_force_reaches_the_wire(make_rig):
    """[simulator] torque_noise / normal_force_noise: the spread of readings at rest through
    the driver (the campaign's noise axis on the shear rig)."""
    import numpy as np

    assert shear().torque_noise == pytest.approx(1e-7)
    spreads = {}
    for level in (1e-7, 2e-5):
        rig = make_rig("shear", simulator={"torque_noise": level,
                                            "normal_force_noise": level * 200})
        rig.rheometer.zero_gap()
        torque = [rig.rheometer.torque() for _ in range(60)]
        normal = [rig.rheometer.normal_force() for _ in range(60)]
        spreads[level] = (float(np.std(torque)), float(np.std(normal)))
    assert spreads[2e-5][0] == pytest.approx(2e-5, rel=0.35)
    assert spreads[2e-5][0] > 20 * spreads[1e-7][0]
    assert spreads[2e-5][1] == pytest.approx(4e-3, rel=0.35)
