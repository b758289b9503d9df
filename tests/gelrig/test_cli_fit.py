"""``gelrig fit relaxation``: which terms the data resolve, and undetermined errors (issue 14).

The holds are the model's ramp and 3000 s hold at the paper's 100 Hz with the simulated rig's
load-cell noise (0.2 mN); docs/decisions/0160 gives the rule.
"""

import json

import numpy as np
import pytest

from gelrig.cli import main
from gelrig.instrument.core.csvio import write_columns
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold
from gelrig.instrument.physics.contact import Material

R, D, V = paper.R_COMPRESSION, paper.DEPTH_HOLD, paper.RAMP_SPEED
NOISE = 2e-4  # N


def hold_csv(path, material, seed, step=1):
    """A noisy modelled hold written as a CSV (every ``step``-th sample: a decimated copy)."""
    rec = ramp_hold(R, D, V, paper.HOLD, material, dt=0.01)
    force = rec.force + np.random.default_rng(seed).normal(0.0, NOISE, rec.force.size)
    return write_columns(path, {"t_s": rec.t[::step], "delta_m": rec.delta[::step],
                                "force_N": force[::step]})


def fit(capsys, path, terms=2):
    assert main(["fit", "relaxation", str(path), "--radius", f"{R}", "--depth", f"{D}",
                 "--terms", str(terms)]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def test_one_term_hold_fitted_with_two_resolves_one(tmp_path, capsys):
    out, err = fit(capsys, hold_csv(tmp_path / "plates.csv", paper.PLATES, 21))
    assert out["terms_resolved"] == 1 and out["terms_requested"] == 2
    assert {"G_e", "relax", "t0_s", "rmse", "stderr"} <= set(out)  # the keys it always had
    assert len(out["relax"]) == 1
    assert out["relax"][0]["tau"] == pytest.approx(1413.0, rel=0.02)
    assert out["G_e"] == pytest.approx(7146.0, rel=0.005)
    assert out["not_resolved"].startswith("second term not resolved: ")
    assert len(out["unresolved_fit"]["relax"]) == 2
    assert err.strip().splitlines() == [f"gelrig fit: {out['not_resolved']}; reporting 1 term(s)"]


def test_the_shells_two_terms_are_resolved(tmp_path, capsys):
    out, err = fit(capsys, hold_csv(tmp_path / "shell.csv", paper.SHELL, 22))
    assert out["terms_resolved"] == 2 and "not_resolved" not in out and err == ""
    assert [r["tau"] for r in out["relax"]] == pytest.approx([1898.0, 172.0], rel=0.05)
    assert all(v is not None and v > 0 for v in out["stderr"].values())


def test_a_decimated_copy_prints_undetermined_errors(tmp_path, capsys):
    """31 samples of the one-term hold: the two-term covariance is singular."""
    out, _ = fit(capsys, hold_csv(tmp_path / "decimated.csv", paper.PLATES, 0, step=1000))
    assert out["terms_resolved"] == 1
    assert "undetermined" in out["not_resolved"]
    assert set(out["unresolved_fit"]["stderr"].values()) == {None}  # never 0.0
    assert all(v is None or v > 0 for v in out["stderr"].values())


def test_one_term_keeps_the_old_shape(tmp_path, capsys):
    out, err = fit(capsys, hold_csv(tmp_path / "plates.csv", paper.PLATES, 23), terms=1)
    assert out["terms_resolved"] == 1 and err == ""
    assert set(out) == {"G_e", "relax", "t0_s", "rmse", "stderr", "relax_ramp_corrected",
                        "terms_resolved", "resolved"}


def test_a_hold_that_resolves_no_term_reports_no_values(tmp_path, capsys):
    """ADR 0261: a purely elastic hold (nothing relaxes) resolves no term; the JSON says
    ``resolved: false`` and why, and its values are only under ``unresolved_fit``."""
    rec = ramp_hold(R, D, V, 300.0, Material(7146.0, ()), dt=0.01)
    force = rec.force + np.random.default_rng(5).normal(0.0, NOISE, rec.force.size)
    path = write_columns(tmp_path / "elastic.csv", {"t_s": rec.t, "delta_m": rec.delta,
                                                     "force_N": force})
    out, err = fit(capsys, path, terms=1)
    assert out["resolved"] is False and out["terms_resolved"] == 0
    assert not {"G_e", "relax", "stderr", "rmse", "t0_s"} & set(out)  # no values as a result
    assert out["not_resolved"] and out["terms_requested"] == 1
    assert len(out["unresolved_fit"]["relax"]) == 1 and "G_e" in out["unresolved_fit"]
    assert err.strip() == f"gelrig fit: not resolved: {out['not_resolved']}; no result"


def test_a_resolved_fit_says_so(tmp_path, capsys):
    out, _ = fit(capsys, hold_csv(tmp_path / "plates.csv", paper.PLATES, 24), terms=1)
    assert out["resolved"] is True and out["G_e"] == pytest.approx(7146.0, rel=0.005)
