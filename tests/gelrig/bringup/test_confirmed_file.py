"""The confirmed rig file: the user's file intact but for the confirmed lines."""

from __future__ import annotations

import pytest

from gelrig.bringup.confirmed_file import Confirmed, apply, write
from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.rigfile import default_rig

BUILT_IN = default_rig("compression").read_text()


def _c(table: str, key: str, value: float | str) -> Confirmed:
    return Confirmed(table, key, value, "a method", "1.2 (0.1 %)", "ana", "2026-11-28T10:00Z")


def test_only_the_confirmed_lines_change_and_the_old_value_is_kept():
    out = apply(BUILT_IN, [_c("stage", "counts_per_mm", 34304.5),
                           _c("force.chain", "rated_output", "2.06 mV/V")])
    before, after = BUILT_IN.splitlines(), out.splitlines()
    changed = [ln for ln in after if ln not in before]
    assert changed == [
        "# was: counts_per_mm = 34554.96",
        "counts_per_mm = 34304.5  # confirmed: 2026-11-28T10:00Z | operator: ana | method: "
        "a method | u: 1.2 (0.1 %)",
        '# was: rated_output = "2 mV/V"',
        'rated_output = "2.06 mV/V"  # confirmed: 2026-11-28T10:00Z | operator: ana | '
        "method: a method | u: 1.2 (0.1 %)"]
    assert [ln for ln in before if ln not in after] == ['counts_per_mm = 34554.96',
                                                        'rated_output = "2 mV/V"']


def test_the_unverified_mark_goes_and_the_rest_of_the_comment_stays():
    text = BUILT_IN.replace("gain = 1000", "gain = 1000   # UNVERIFIED (ADR 0010): no datasheet")
    out = apply(text, [_c("force.chain", "gain", 998.0)])
    assert "# was: gain = 1000  -- (ADR 0010): no datasheet" in out
    assert "UNVERIFIED" not in out


def test_a_key_the_file_lacks_is_added_to_its_table():
    out = apply(BUILT_IN, [_c("force.chain", "noise", "0.35 mN")])
    chain = out.split("[force.chain]")[1].split("[limits]")[0]
    assert 'noise = "0.35 mN"  # confirmed:' in chain


def test_a_confirmed_value_the_rig_file_refuses_is_one_line_and_nothing_written(tmp_path):
    rig = tmp_path / "rig.toml"
    rig.write_text(BUILT_IN)
    out = tmp_path / "confirmed.toml"
    with pytest.raises(ConfigError) as err:
        write(rig, out, [_c("stage", "counts_per_mm", -3.0)])
    assert "[stage] counts_per_mm = -3.0" in str(err.value) and "\n" not in str(err.value)
    assert not out.exists()


def test_a_multi_line_value_is_not_rewritten():
    text = BUILT_IN.replace('relax = [["630 Pa", "1413 s"]]',
                            'relax = [\n  ["630 Pa", "1413 s"],\n]')
    with pytest.raises(ConfigError, match="one-line value"):
        apply(text, [_c("simulator", "relax", "x")])
