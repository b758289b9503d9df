"""`gelrig model --unloading cutoff|mdr` (docs/decisions/0150)."""

import numpy as np
import pytest

from gelrig.cli import main
from gelrig.instrument.core.csvio import read_columns

SHEAR = ["model", "shear", "--r1", "9.2e-3", "--r2", "9.96e-3", "--delta-max", "0.78 mm",
         "--speed", "2.37e-4", "--g-e", "4 kPa", "--relax", "20 kPa:2000 s", "--mu", "5e-3"]
COMP = ["model", "compression", "--radius", "9.315 mm", "--depth", "1.1178 mm",
        "--rate", "37.26 um/s", "--hold", "60 s", "--g-e", "7146", "--relax", "630:1413 s"]
COLS = ["t_s", "psi_m", "delta_m", "f_perp_N", "f_h_N", "f_v_N"]


def _shear(tmp_path, unloading):
    out = tmp_path / f"{unloading}.csv"
    extra = [] if unloading is None else ["--unloading", unloading]
    assert main([*SHEAR, "--margin", "0.1mm", *extra, "--out", str(out)]) == 0
    return read_columns(out, COLS)


def test_default_is_the_cutoff_and_mdr_differs_only_while_unloading(tmp_path):
    default, cutoff, mdr = (_shear(tmp_path, u) for u in (None, "cutoff", "mdr"))
    np.testing.assert_array_equal(default["f_perp_N"], cutoff["f_perp_N"])
    np.testing.assert_array_equal(mdr["delta_m"], cutoff["delta_m"])
    growing = mdr["psi_m"] > 0  # approaching: the overlap only grows
    peak = cutoff["f_perp_N"].max()
    np.testing.assert_allclose(mdr["f_perp_N"][growing], cutoff["f_perp_N"][growing],
                               rtol=0, atol=1e-4 * peak)
    # departing, MDR keeps the contact longer (Ting): it ends later than the cutoff's
    assert np.flatnonzero(mdr["f_perp_N"] > 0)[-1] > np.flatnonzero(cutoff["f_perp_N"] > 0)[-1]
    assert np.all(mdr["f_perp_N"] >= 0)
    f_h, f_perp, psi = mdr["f_h_N"], mdr["f_perp_N"], mdr["psi_m"]
    h = 9.2e-3 + 9.96e-3 - 0.78e-3
    np.testing.assert_allclose(f_h, f_perp * (psi + 5e-3 * h) / np.hypot(h, psi), rtol=1e-8,
                               atol=1e-15)


def test_compression_with_mdr_equals_the_cutoff_on_ramp_and_hold(tmp_path):
    forces = {}
    for unloading in ("cutoff", "mdr"):
        out = tmp_path / f"c_{unloading}.csv"
        assert main([*COMP, "--unloading", unloading, "--out", str(out)]) == 0
        forces[unloading] = read_columns(out, ["t_s", "delta_m", "force_N"])["force_N"]
    np.testing.assert_allclose(forces["mdr"], forces["cutoff"], rtol=0,
                               atol=1e-4 * forces["cutoff"].max())


@pytest.mark.parametrize("command", [SHEAR, COMP])
def test_bad_unloading_is_one_line_and_exit_2(tmp_path, capsys, command):
    assert main([*command, "--unloading", "ting", "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "--unloading" in err and "ting" in err and "cutoff" in err and "mdr" in err
