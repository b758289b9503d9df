"""The shear rig's twin: the rheometer simulator is the rig file's truth, on the rig's arm."""

from __future__ import annotations

import dataclasses

import pytest

from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.truth import ShearSample, ShearTruth
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.twins.shear import shear_simulator


def test_the_simulator_takes_every_field_of_the_truth_and_the_arm() -> None:
    truth = ShearTruth.from_table({
        "r1": "9 mm", "r2": "10 mm", "mu": 0.01, "lower_angle": "45 deg", "touch_gap": "2 mm",
        "seed": 5, "unloading": "mdr", "torque_noise": 2e-7, "normal_force_noise": 1e-5,
        "carry_history": True, "g_e": "5 kPa", "relax": [["10 kPa", "1000 s"]],
        "relax_vertical": [["8 kPa", "1000 s"]], "link": "direct"}, "rig.toml")
    sim = shear_simulator(VirtualClock(), truth, RheometerConfig(arm=0.03))
    for f in dataclasses.fields(ShearSample):
        assert getattr(sim.config, f.name) == getattr(truth, f.name), f.name
    assert sim.config.arm == 0.03
    assert sim.config.material_vertical == Material.of(5e3, [(8e3, 1000.0)])
    assert type(sim.config.seed) is int  # numpy's generators take integer seeds


def test_the_defaults_are_declared_once() -> None:
    """The rig file's truth, the simulator and the paper agree without a translation."""
    assert SimConfig.of(ShearTruth(), RheometerConfig()) == SimConfig()
    config = SimConfig()
    assert (config.r1, config.r2, config.mu, config.arm) == (
        paper.R1_SHEAR, paper.R2_SHEAR, paper.MU, paper.ARM)
    assert config.material == paper.SHEAR_FH
    rheometer = RheometerConfig()
    assert (config.torque_range, config.overlap_limit, config.gap_max) == (
        rheometer.torque_range, rheometer.overlap_limit, rheometer.gap_max)


def test_the_built_in_rig_gives_its_truth_to_the_simulator() -> None:
    spec = load_rig(default_rig("shear"))
    sim = shear_simulator(VirtualClock(), spec.simulator, spec.rheometer.config)
    assert sim.config.touch_gap == spec.simulator.touch_gap
    assert sim.config.material == spec.simulator.material


def test_a_bad_value_names_the_field() -> None:
    with pytest.raises(ValueError, match=r"\[simulator\] touch_gap"):
        SimConfig(touch_gap=25e-3, gap_min=0.0)  # deeper than R1 + R2
