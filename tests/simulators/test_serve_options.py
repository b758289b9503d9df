"""The light option table of ``gelrig sim serve`` matches the serve modules it stands for, and
its options are the simulators' configuration fields (one declaration, one default)."""

import argparse
import importlib

import pytest

from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.options import config_from_options, option, shown_default
from gelrig.instrument.physics.truth import ShearTruth
from gelrig.simulators.kdc101.config import SimConfig as Kdc101Config
from gelrig.simulators.mcr501.config import SimConfig as Mcr501Config
from gelrig.simulators.serve_options import MCR501_OPTIONS, SERVED
from gelrig.simulators.usb6001.config import Standalone


@pytest.mark.parametrize("name", sorted(SERVED))
def test_summary_and_options_are_the_serve_modules_own(name):
    served = SERVED[name]
    module = importlib.import_module(served.module)
    assert served.summary == module.__doc__.strip().splitlines()[0]
    assert module.add_arguments is served.add_arguments
    assert callable(module.run)



def _parser(name: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=f"gelrig sim serve {name}")
    SERVED[name].add_arguments(parser)
    return parser


@pytest.mark.parametrize(("name", "cls", "only"), [
    ("kdc101", Kdc101Config, None), ("usb6001", Standalone, None),
    ("mcr501", Mcr501Config, MCR501_OPTIONS)])
def test_options_are_the_configs_fields_with_their_defaults(name, cls, only):
    """Every option of the simulated hardware or sample is a config field, its default the
    field's; left out, the config is the default one."""
    parser = _parser(name)
    help_text = " ".join(parser.format_help().split())
    fields = {n: s for n, s in cls.specs().items() if only is None or n in only}
    for spec in fields.values():
        assert option(spec) in help_text
        if spec.initial() is not None:
            assert f"(default {shown_default(spec)})" in help_text, spec.key
    required = ["--tcp", "127.0.0.1:0"] if name == "kdc101" else []
    assert config_from_options(cls, parser.parse_args(required), "x", only) == cls()


def test_help_shows_the_defaults_the_rig_file_documents():
    kdc101 = " ".join(_parser("kdc101").format_help().split())
    assert "(default 34554.96)" in kdc101 and "(default 25 mm)" in kdc101
    assert "(default 0.1 mm)" in kdc101 and "(default forward_is_negative)" in kdc101
    assert StageConfig().counts_per_mm == Kdc101Config().counts_per_mm  # the one default
    mcr501 = " ".join(_parser("mcr501").format_help().split())
    truth = ShearTruth()
    assert f"(default {truth.touch_gap * 1e3:g} mm)" in mcr501
    assert f"(default {truth.r1 * 1e3:g} mm)" in mcr501 and "(default 27 mm)" in mcr501


def test_options_are_read_by_the_fields_own_parsers():
    parser = _parser("mcr501")
    args = parser.parse_args(["--touch-gap", "2.5 mm", "--lower-angle", "45 deg", "--seed", "3",
                              "--carry-history", "--unloading", "mdr"])
    config = config_from_options(Mcr501Config, args, "gelrig sim serve mcr501", MCR501_OPTIONS)
    assert config.touch_gap == pytest.approx(2.5e-3)
    assert config.lower_angle == pytest.approx(0.785398, rel=1e-5)
    assert (config.seed, config.carry_history, config.unloading) == (3, True, "mdr")
    args = _parser("kdc101").parse_args(["--pty", "--home-offset", "0.2 mm",
                                         "--serial", "27555555"])
    config = config_from_options(Kdc101Config, args, "gelrig sim serve kdc101")
    assert config.home_offset_m == pytest.approx(0.2e-3) and config.serial_number == 27555555
    with pytest.raises(ConfigError, match=r"gelrig sim serve kdc101: --travel = \"3 N\""):
        config_from_options(Kdc101Config, _parser("kdc101").parse_args(
            ["--pty", "--travel", "3 N"]), "gelrig sim serve kdc101")
    with pytest.raises(ConfigError, match="--serial = 83000001: a KDC101 serial is 27xxxxxx"):
        config_from_options(Kdc101Config, _parser("kdc101").parse_args(
            ["--pty", "--serial", "83000001"]), "gelrig sim serve kdc101")


@pytest.mark.parametrize("name", ["kdc101", "usb6001"])
def test_timing_is_ideal_unless_documented_is_asked_for(name):
    """ADR 0242: ``--timing documented`` gives the devices' documented timing; the default
    stays ideal."""
    from gelrig.simulators.usb6001.device import DOCUMENTED

    parser = _parser(name)
    required = ["--tcp", "127.0.0.1:0"] if name == "kdc101" else []
    cls = Kdc101Config if name == "kdc101" else Standalone
    ideal = config_from_options(cls, parser.parse_args(required), "x")
    documented = config_from_options(
        cls, parser.parse_args([*required, "--timing", "documented"]), "x")
    assert (ideal.timing, documented.timing) == ("ideal", "documented")
    if name == "kdc101":
        assert ideal.reply_latency == 0.0 and documented.reply_latency == 0.016
        given = config_from_options(cls, parser.parse_args(
            [*required, "--timing", "documented", "--reply-latency", "0.002"]), "x")
        assert given.reply_latency == 0.002  # a field given overrides the preset
    else:
        assert DOCUMENTED.drift_ppm == 100.0 and DOCUMENTED.transfer == 32


def test_rig_file_timing_documented_sets_every_twin_field_it_does_not_give():
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.instrument.physics.truth import CompressionTruth
    from gelrig.simulators.twins.compression import daq_timing, stage_simulator
    from gelrig.simulators.usb6001.device import DOCUMENTED, DaqTiming

    ideal = CompressionTruth.from_table({})
    assert daq_timing(ideal) == DaqTiming(seed=int(ideal.seed))
    truth = CompressionTruth.from_table({"timing": "documented", "daq_jitter": "0 s"})
    assert daq_timing(truth) == DaqTiming(DOCUMENTED.drift_ppm, DOCUMENTED.latency, 0.0,
                                          DOCUMENTED.transfer, seed=int(truth.seed))
    sim = stage_simulator(VirtualClock(), StageConfig(), truth)
    assert sim.config.reply_latency == 0.016
    with pytest.raises(ConfigError):
        CompressionTruth.from_table({"timing": "fast"})
