"""StageConfig: the [stage] table of a rig file, validated field by field."""

from __future__ import annotations

import pytest

from gelrig.instrument.contracts.stage import StageConfig
from gelrig.instrument.core.errors import ConfigError, LimitError


def test_defaults_are_the_protocol_documents_factors() -> None:
    c = StageConfig()
    assert (c.counts_per_mm, c.velocity_factor, c.accel_factor) == (34554.96, 772981.3692,
                                                                    263.8443072)
    assert c.counts_from_m(1e-3) == 34555
    assert c.apt_velocity(2.3e-3) == round(2.3 * 772981.3692)
    assert c.m_from_counts(34555) == pytest.approx(1e-3, rel=2e-5)


def test_from_table_accepts_units_and_si_numbers() -> None:
    c = StageConfig.from_table(
        {"counts_per_mm": 34304, "max_position": "11.5 mm", "max_velocity": "1.2 mm/s",
         "acceleration": 0.002, "move_timeout": "2 min"}, "rig.toml")
    assert c.counts_per_mm == 34304
    assert c.max_position_m == pytest.approx(11.5e-3)
    assert c.max_velocity_m_s == pytest.approx(1.2e-3)
    assert c.acceleration_m_s2 == 0.002
    assert c.move_timeout_s == pytest.approx(120)
    assert StageConfig.from_table(c.to_table(), "round trip") == c


@pytest.mark.parametrize(
    ("table", "field", "says"),
    [
        ({"max_velocity": "5 mm/s"}, "[stage] max_velocity",
         "= \"5 mm/s\": allowed (0, 2.6] mm/s"),
        ({"max_position": "30 mm"}, "[stage] max_position",
         "= \"30 mm\": allowed [0, 25] mm"),
        ({"counts_per_mm": 0}, "[stage] counts_per_mm", "= 0: allowed (1000,"),
        ({"min_position": "5 mm", "max_position": "4 mm"}, "[stage] min_position", "< max"),
        ({"max_velocity": "2 mm"}, "[stage] max_velocity", "dimension"),
        ({"speed": 1}, "[stage] speed", "unknown field"),
        ({"poll_interval": True}, "[stage] poll_interval", "expected a number"),
    ],
)
def test_bad_values_name_file_field_and_range(table: dict[str, object], field: str, says: str
                                              ) -> None:
    with pytest.raises(ConfigError) as info:
        StageConfig.from_table(table, "rigs/compression.toml")
    assert info.value.field == field
    assert info.value.source == "rigs/compression.toml"
    assert says in str(info.value)


def test_limit_checks() -> None:
    c = StageConfig(min_position_m=1e-3, max_position_m=10e-3)
    c.check_position(1e-3)
    c.check_position(10e-3)
    for bad in (0.999e-3, 10.001e-3, float("nan")):
        with pytest.raises(LimitError, match="nothing moved"):
            c.check_position(bad)
    with pytest.raises(LimitError):
        c.check_velocity(0.0, 1e-3)
