"""The rheometer contract's configuration: defaults, rig-file loading, validation messages."""

from __future__ import annotations

import dataclasses
import math

import pytest

from gelrig.instrument.contracts.rheometer import (
    Rheometer,
    RheometerConfig,
    RheometerStatus,
    StreamPoint,
)
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.identity import Identity


def test_defaults_are_the_papers_arm_and_placeholder_limits() -> None:
    cfg = RheometerConfig()
    assert cfg.arm == 0.027
    assert cfg.touch_gap is None
    assert cfg.deepest_gap() == cfg.gap_min
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.arm = 0.03  # type: ignore[misc]


def test_from_table_accepts_units_at_the_edge() -> None:
    table = {"arm": "27 mm", "torque_range": "150 mN*m", "max_speed": "0.3 mm/s"}
    cfg = RheometerConfig.from_table({**table, "touch_gap": 2.5e-3, "timeout": 1})
    assert cfg.arm == pytest.approx(0.027)
    assert cfg.torque_range == pytest.approx(0.15)
    assert cfg.max_speed == pytest.approx(3e-4)
    assert cfg.timeout == 1.0
    assert cfg.deepest_gap() == pytest.approx(2.5e-3 - cfg.overlap_limit)
    assert RheometerConfig.from_table({"touch_gap": None}).touch_gap is None


@pytest.mark.parametrize(
    ("mapping", "field", "allowed"),
    [
        ({"arm": -0.027}, "[rheometer] arm", "allowed [0.001, 0.5] m"),
        ({"arm": "27 N"}, "[rheometer] arm", "dimension mismatch"),
        ({"torque_range": 0}, "[rheometer] torque_range", "allowed (0, 1] N*m"),
        ({"max_speed": math.inf}, "[rheometer] max_speed", "finite"),
        ({"overlap_limit": "2 cm"}, "[rheometer] overlap_limit", "allowed (0, 1] cm"),
        ({"gap_min": 0.03, "gap_max": 0.02}, "[rheometer] gap_min", "must be < gap_max"),
        ({"colour": "red"}, "[rheometer] colour", "unknown field"),
        ({"timeout": True}, "[rheometer] timeout", "expected a number"),
        ({"poll_interval": [1]}, "[rheometer] poll_interval", "expected a number"),
    ],
)
def test_bad_values_name_source_field_value_and_range(
    mapping: dict[str, object], field: str, allowed: str
) -> None:
    with pytest.raises(ConfigError) as err:
        RheometerConfig.from_table(mapping, source="rig.toml [rheometer]")
    assert err.value.field == field
    assert err.value.source == "rig.toml [rheometer]"
    assert allowed in str(err.value)
    assert str(err.value).startswith(f"rig.toml [rheometer]: {field} = ")


def test_direct_construction_validates_too() -> None:
    with pytest.raises(ConfigError, match="arm"):
        RheometerConfig(arm=0.0)


def test_speed_check() -> None:
    cfg = RheometerConfig(max_speed=1e-3)
    assert cfg.speed_allowed(-1e-3) and cfg.speed_allowed(0.0)
    assert not cfg.speed_allowed(1.01e-3)
    assert not cfg.speed_allowed(math.nan)


def test_status_busy_and_stream_point() -> None:
    idle = RheometerStatus("idle", False, True, False, False, False, False)
    assert not idle.busy
    assert dataclasses.replace(idle, gap_moving=True).busy
    assert dataclasses.replace(idle, mode="rotating").busy
    assert not dataclasses.replace(idle, mode="holding").busy
    p = StreamPoint(1.0, 0.1, 0.0027, 1e-4, 0.09, 2.2e-3)
    assert p.theta == pytest.approx(p.angle * 0.027)


def test_protocol_is_structural() -> None:
    class Partial:
        def identify(self) -> Identity:
            return Identity("x", "y", "1")

    assert not isinstance(Partial(), Rheometer)
