"""The one configuration reader: every config dataclass, one error format, units as written."""

from __future__ import annotations

import dataclasses
import math

import pytest

from gelrig.instrument.contracts.daq import Usb6001Config
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.contracts.rheometer import RheometerConfig
from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.fields import (
    Choice,
    Config,
    Field,
    Flag,
    Text,
    Where,
    param,
    read_toml,
)
from gelrig.protocols.rig import CompressionLimits, ShearLimits
from gelrig.protocols.rigfile import CompressionTruth, ShearTruth

CONFIGS: list[type[Config]] = [StageConfig, Usb6001Config, LoadCellChain, RheometerConfig,
                               CompressionLimits, ShearLimits, CompressionTruth, ShearTruth]


@pytest.mark.parametrize("cls", CONFIGS)
def test_every_config_field_carries_its_spec_and_defaults_are_valid(cls: type[Config]) -> None:
    specs = cls.specs()
    plain = {f.name for f in dataclasses.fields(cls)} - set(specs)  # type: ignore[arg-type]
    # read by their own parsers: Prony lists (material, relax_vertical) and a TOML boolean
    assert plain <= {"material", "material_vertical", "carry_history"}
    default = cls()  # defaults live once, on the field, and satisfy the field's own range
    assert cls.from_table({}) == default
    assert cls.from_table(default.to_table()) == default  # SI numbers read back unchanged
    for spec in specs.values():
        assert spec.allowed().startswith("allowed")


# One format: `source: [table] key = value as written: allowed ... in the unit written`.
@pytest.mark.parametrize(("cls", "table", "message"), [
    # a number out of range, written with a unit: the range in that unit
    (StageConfig, {"max_velocity": "9 mm/s"},
     'rig.toml: [stage] max_velocity = "9 mm/s": allowed (0, 2.6] mm/s'),
    (RheometerConfig, {"arm": "80 cm"},
     'rig.toml: [rheometer] arm = "80 cm": allowed [0.1, 50] cm'),
    # a bare number is SI: the range in SI
    (LoadCellChain, {"gain": -1.0}, "rig.toml: [force.chain] gain = -1.0: allowed (0, 100000] V/V"),
    (Usb6001Config, {"buffer_seconds": "2 h"},
     'rig.toml: [force] buffer_seconds = "2 h": allowed [2.77778e-05, 1] h'),
    # integers
    (CompressionTruth, {"seed": 1.5},
     "rig.toml: [simulator] seed = 1.5: allowed an integer in [0, 2.14748e+09]"),
    # words
    (Usb6001Config, {"terminal": "nrse"},
     'rig.toml: [force] terminal = "NRSE": allowed: RSE, DIFF'),
    (ShearTruth, {"link": "usb"}, 'rig.toml: [simulator] link = "usb": allowed: tcp, direct'),
    # a wrong kind of value
    (ShearLimits, {"max_torque": True},
     "rig.toml: [limits] max_torque = true: expected a number; allowed (0, 1] N*m"),
    (Usb6001Config, {"device": "Dev1/ai0"},
     'rig.toml: [force] device = "Dev1/ai0": allowed: a DAQmx device name such as \'Dev1\''),
    # unknown keys list what is allowed
    (CompressionLimits, {"max_forse": 1},
     "rig.toml: [limits] max_forse = 1: unknown field; allowed: acceleration, fast_speed, "
     "max_force, max_overlap, retract_on_fault, watchdog"),
    # a check across fields names the file too
    (StageConfig, {"min_position": "5 mm", "max_position": "4 mm"},
     "rig.toml: [stage] min_position = 0.005: must be < max_position (0.004 m)"),
    (Usb6001Config, {"terminal": "DIFF", "channel": "ai5"},
     'rig.toml: [force] channel = "ai5": allowed with DIFF: ai0..ai3'),
])
def test_one_error_format(cls: type[Config], table: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as info:
        cls.from_table(table, "rig.toml")
    assert str(info.value) == message


def test_dimension_mismatch_and_garbage_name_the_unit() -> None:
    with pytest.raises(ConfigError, match=r'\[stage\] max_velocity = "2 mm": .*m/s'):
        StageConfig.from_table({"max_velocity": "2 mm"})
    with pytest.raises(ConfigError, match=r"\[stage\] max_velocity = \"fast\""):
        StageConfig.from_table({"max_velocity": "fast"})


def test_constructed_in_code_obeys_the_same_ranges() -> None:
    with pytest.raises(ConfigError, match=r"^\[limits\] max_force = -1.0: allowed \(0, 100\] N$"):
        CompressionLimits(max_force=-1.0)
    with pytest.raises(ConfigError, match=r"\[simulator\] mu = nan"):
        ShearTruth(mu=math.nan)


def test_a_new_config_is_one_declaration() -> None:
    @dataclasses.dataclass(frozen=True)
    class Pump(Config):
        section = "pump"
        rate: float = param(Field("rate", "m^3/s", None, 0.0, 1e-3, lo_open=True))
        mode: str = param(Choice("mode", ("push", "pull"), "push"))
        label: str = param(Text("label", "p1"))

    with pytest.raises(ConfigError, match=r"\[pump\] rate = \"missing\": required"):
        Pump.from_table({})
    pump = Pump.from_table({"rate": "1 mL/s", "mode": "pull"})
    assert pump.rate == pytest.approx(1e-6) and pump.mode == "pull" and pump.label == "p1"


def test_where_names_nested_tables() -> None:
    where = Where("force", "rig.toml").sub("chain")
    assert str(where.error("gain", 0, "x")) == "rig.toml: [force.chain] gain = 0: x"


@pytest.mark.parametrize(("content", "needle"), [
    ("[rig]\nkind = 'x'".encode("utf-16"), "not UTF-8"),
    (b"a = " + b"[" * 200 + b"]" * 200, "nested deeper"),
    (b"[rig\n", "not valid TOML"),
])
def test_toml_files_that_cannot_be_read_are_one_line(tmp_path, content: bytes, needle: str
                                                     ) -> None:
    path = tmp_path / "rig.toml"
    path.write_bytes(content)
    with pytest.raises(ConfigError) as info:
        read_toml(path, "rig file")
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_a_flag_is_a_toml_boolean_and_exact_integers_are_ints() -> None:
    @dataclasses.dataclass(frozen=True)
    class Valve(Config):
        section = "valve"
        exact_integers = True
        open: bool = param(Flag("open", False))
        turns: int = param(Field("turns", "", 2, 1, 10, integer=True))

    valve = Valve.from_table({"open": True, "turns": "3"})
    assert valve.open is True and valve.turns == 3 and type(valve.turns) is int
    assert Valve.from_table({"open": "false"}).open is False
    with pytest.raises(ConfigError, match=r'\[valve\] open = "yes": allowed: true or false'):
        Valve.from_table({"open": "yes"})
    with pytest.raises(ConfigError, match=r"\[valve\] turns = 2.5: allowed an integer"):
        Valve(turns=2.5)
