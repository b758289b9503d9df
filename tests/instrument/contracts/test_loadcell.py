"""The load-cell chain: conversions, validation at the edges, the force-sensor contract."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gelrig.instrument.contracts.loadcell import (
    AcquisitionTimeoutError,
    ForceBlock,
    ForceSensor,
    LoadCellChain,
)
from gelrig.instrument.core.errors import ConfigError, InstrumentTimeout


def test_default_chain_maps_rated_load_to_ten_volts() -> None:
    chain = LoadCellChain()
    assert chain.sensitivity == pytest.approx(4.0)  # 2 mV/V * 5 V * 1000 / 2.5 N
    assert chain.full_scale_volts == pytest.approx(10.0)
    assert float(chain.volts(2.5)) == pytest.approx(10.0)


def test_offset_and_tare_zero() -> None:
    chain = LoadCellChain(offset=0.05)
    assert float(chain.volts(0.0)) == pytest.approx(0.05)
    assert float(chain.newtons(0.05)) == pytest.approx(0.0)
    # A tare that found 0.07 V at no load makes 0.07 V read as zero force.
    assert float(chain.newtons(0.07, zero=0.07)) == pytest.approx(0.0)
    assert float(chain.newtons(0.47, zero=0.07)) == pytest.approx(0.1)


@given(
    force=st.floats(-3.0, 3.0),
    rated=st.floats(0.5e-3, 3e-3),
    gain=st.floats(10.0, 5000.0),
    offset=st.floats(-1.0, 1.0),
)
def test_volts_newtons_round_trip(force: float, rated: float, gain: float, offset: float) -> None:
    chain = LoadCellChain(rated_output=rated, gain=gain, offset=offset)
    assert float(chain.newtons(chain.volts(force))) == pytest.approx(force, abs=1e-9)


def test_from_table_accepts_units() -> None:
    chain = LoadCellChain.from_table(
        {"capacity": "250 gram * 9.80665 m/s^2", "rated_output": "1.5 mV/V",
         "excitation": "5 V", "gain": 500, "offset": "12 mV", "bandwidth": "1 kHz"},
        "rig.toml",
    )
    assert chain.capacity == pytest.approx(2.4516625)
    assert chain.rated_output == pytest.approx(1.5e-3)
    assert chain.offset == pytest.approx(0.012)
    assert chain.bandwidth == pytest.approx(1000.0)
    assert chain.gain == 500.0
    assert chain.compliance == 0.0  # stiff unless the rig file says otherwise
    soft = LoadCellChain.from_table({"compliance": "20 um/N"}, "rig.toml")
    assert soft.compliance == pytest.approx(2e-5)


@pytest.mark.parametrize(
    ("mapping", "field", "needle"),
    [
        ({"rated_output": 2}, "[force.chain] rated_output", "(0, 0.01] V/V"),
        ({"capacity": "-1 N"}, "[force.chain] capacity", "(0, 100000] N"),
        ({"offset": "11 V"}, "[force.chain] offset", "[-10.5, 10.5] V"),
        ({"excitation": "5 A"}, "[force.chain] excitation", "dimension"),
        ({"gain": True}, "[force.chain] gain", "number"),
        ({"gain": [1]}, "[force.chain] gain", "number"),
        ({"sensitivity": 4}, "[force.chain] sensitivity", "unknown field"),
        ({"compliance": "-1 um/N"}, "[force.chain] compliance", "[0, 10000] um/N"),
        ({"compliance": "3 mm"}, "[force.chain] compliance", "dimension"),
    ],
)
def test_from_table_names_field_value_and_range(
    mapping: dict[str, object], field: str, needle: str
) -> None:
    with pytest.raises(ConfigError) as info:
        LoadCellChain.from_table(mapping, "rig.toml")
    assert info.value.field == field
    assert info.value.source == "rig.toml"
    assert needle in str(info.value)
    assert str(info.value).startswith("rig.toml: ")


def test_constructor_validates_too() -> None:
    with pytest.raises(ConfigError, match="bandwidth"):
        LoadCellChain(bandwidth=0.0)


def test_force_block_flags() -> None:
    z = np.zeros(3)
    block = ForceBlock(z, z, z, np.array([False, True, False]))
    assert len(block) == 3
    assert block.any_over_range
    err = AcquisitionTimeoutError("late", block)
    assert isinstance(err, InstrumentTimeout) and err.block is block


def test_force_sensor_protocol_rejects_incomplete_objects() -> None:
    class Half:
        def start(self, rate_hz: float) -> None: ...

    assert not isinstance(Half(), ForceSensor)
