"""The CLI contract of `gelrig model` / `gelrig fit` / `gelrig demo` and its bad-input errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

from gelrig.cli import main
from gelrig.instrument.core.csvio import read_columns
from gelrig.instrument.physics import paper

COMP = ["model", "compression", "--radius", "9.315 mm", "--depth", "1.1178 mm",
        "--rate", "37.26 um/s", "--hold", "600 s", "--g-e", "7146", "--relax", "630:1413 s"]
SHEAR = ["model", "shear", "--r1", "9.2e-3", "--r2", "9.96e-3", "--delta-max", "0.78 mm",
         "--speed", "2.38e-5", "--g-e", "4 kPa", "--relax", "20 kPa:2000 s", "--mu", "5e-3"]


def test_model_compression_then_fit(tmp_path, capsys):
    out = tmp_path / "c.csv"
    assert main([*COMP, "--out", str(out)]) == 0
    cols = read_columns(out, ["t_s", "delta_m", "force_N"])
    assert out.read_text().splitlines()[0] == "t_s,delta_m,force_N"
    assert cols["delta_m"].max() == pytest.approx(1.1178e-3)
    assert cols["t_s"][-1] == pytest.approx(1.1178e-3 / 37.26e-6 + 600, abs=0.011)
    capsys.readouterr()
    assert main(["fit", "relaxation", str(out), "--radius", "9.315mm", "--depth", "1.1178mm"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["G_e"] == pytest.approx(7146, rel=0.01)
    assert result["relax"][0]["tau"] == pytest.approx(1413, rel=0.02)
    assert result["t0_s"] == pytest.approx(30.0, abs=0.02)
    assert {"rmse", "stderr"} <= set(result)


def test_strain_rate_is_relative_to_the_diameter(tmp_path):
    out = tmp_path / "c.csv"
    args = [a if a != "37.26 um/s" else "0.002/s" for a in COMP]
    assert main([*args, "--out", str(out)]) == 0
    t = read_columns(out, ["t_s", "delta_m"])
    ramp_end = t["t_s"][np.argmax(t["delta_m"] >= t["delta_m"].max())]
    assert ramp_end == pytest.approx(0.06 / 0.002, rel=1e-3)


def test_model_shear_columns_and_physics(tmp_path):
    out = tmp_path / "s.csv"
    assert main([*SHEAR, "--margin", "0.1mm", "--out", str(out)]) == 0
    assert out.read_text().splitlines()[0] == "t_s,psi_m,delta_m,f_perp_N,f_h_N,f_v_N"
    cols = read_columns(out, ["t_s", "psi_m", "delta_m", "f_perp_N", "f_h_N", "f_v_N"])
    assert cols["delta_m"].max() == pytest.approx(0.78e-3, rel=1e-4)
    assert cols["f_h_N"].max() > abs(cols["f_h_N"].min())
    assert cols["psi_m"][0] == pytest.approx(-cols["psi_m"][-1])


def test_demo_model_part_writes_data_plots_and_summary(tmp_path, capsys):
    assert main(["demo", "--no-runs", "--out", str(tmp_path)]) == 0
    names = {p.name for p in (tmp_path / "model").iterdir()}
    assert {"compression_relaxation.png", "shear_passes.png", "compression_plates.csv"} <= names
    summary = json.loads((tmp_path / "summary.json").read_text())["model"]
    plates = summary["compression"]["plates"]["fits"][0]
    assert plates["G_e"] == pytest.approx(7146, rel=0.01)
    rows = summary["shear"]["passes"]
    assert [r["speed_m_s"] for r in rows] == list(paper.SPEEDS)
    assert str(tmp_path.resolve()) in capsys.readouterr().out


BAD = [
    (["--radius", "-1"], "--radius"),
    (["--radius", "0"], "--radius"),
    (["--depth", "0 mm"], "--depth"),
    (["--rate", "-3"], "--rate"),
    (["--dt", "0"], "--dt"),
    (["--nu", "1"], "--nu"),
    (["--nu", "-0.2"], "--nu"),
    (["--relax", "630"], "--relax"),
    (["--relax", "630:0"], "--relax"),
    (["--relax", "abc:1413"], "--relax"),
    (["--radius", "3 s"], "--radius"),
    (["--depth", "20 mm"], "--depth"),
]


@pytest.mark.parametrize("override,option", BAD)
def test_bad_compression_options(tmp_path, capsys, override, option):
    args = list(COMP)
    key = override[0]
    if key in args:
        i = args.index(key)
        args[i:i + 2] = override
    else:
        args += override
    assert main([*args, "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and option in err
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("override,option", [
    (["--delta-max", "20 mm"], "--delta-max"),
    (["--speed", "0"], "--speed"),
    (["--dt", "-1"], "--dt"),
    (["--r1", "0"], "--r1"),
    (["--mu", "-0.1"], "--mu"),
])
def test_bad_shear_options(tmp_path, capsys, override, option):
    args = [a for a in SHEAR]
    if override[0] in args:
        i = args.index(override[0])
        args[i:i + 2] = override
    else:
        args += override
    assert main([*args, "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and option in err


@pytest.mark.parametrize("content,needle", [
    ("t_s,f\n0,1\n", "'force_N'"),
    ("t_s,force_N\n0,1\n1,abc\n", "line 3, column 'force_N'"),
    ("", "empty"),
    ("t_s,force_N\n", "no data"),
    ("t_s,force_N\n0,1\n1\n", "line 3"),
])
def test_bad_csv(tmp_path, capsys, content, needle):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    assert main(["fit", "relaxation", str(path), "--radius", "9e-3", "--depth", "1e-3"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err and "bad.csv" in err


def test_missing_file_and_bad_terms(tmp_path, capsys):
    assert main(["fit", "relaxation", str(tmp_path / "none.csv"), "--radius", "9e-3",
                 "--depth", "1e-3"]) == 2
    assert main(["fit", "relaxation", "x.csv", "--radius", "9e-3", "--depth", "1e-3",
                 "--terms", "3"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2 and "--terms" in lines[1]


def test_console_script_bad_input_has_no_traceback():
    proc = subprocess.run([sys.executable, "-m", "gelrig.cli", *SHEAR, "--relax", "1:x",
                           "--out", "/dev/null"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1 and "--relax" in proc.stderr


def test_model_shear_anisotropic_vertical_force(tmp_path):
    """--relax-vertical: F_v from its own modulus (the paper's G_l = 4 G_e), F_h unchanged."""
    iso, aniso = tmp_path / "iso.csv", tmp_path / "aniso.csv"
    assert main([*SHEAR, "--out", str(iso)]) == 0
    assert main([*SHEAR, "--relax-vertical", "16 kPa:2000 s", "--out", str(aniso)]) == 0
    names = ["f_perp_N", "f_h_N", "f_v_N"]
    a, b = read_columns(iso, names), read_columns(aniso, names)
    assert np.array_equal(a["f_h_N"], b["f_h_N"])
    ratio = b["f_v_N"].max() / a["f_v_N"].max()
    assert 0.8 < ratio < 0.9  # (G_e + 4 G_e) / (G_e + 5 G_e) = 0.83 at the instant of loading


def test_model_shear_unloading_mdr_holds_the_receding_contact_longer(tmp_path, capsys):
    """MDR (physics.md 1b): the same force while the contact grows, never negative, and
    in contact over more of the pass than the cutoff model."""
    runs = {}
    for model in ("cutoff", "mdr"):
        out = tmp_path / f"{model}.csv"
        assert main([*SHEAR, "--unloading", model, "--out", str(out)]) == 0
        runs[model] = read_columns(out, ["psi_m", "f_perp_N"])
    cut, mdr = runs["cutoff"], runs["mdr"]
    assert (mdr["f_perp_N"] >= 0).all()
    growing = cut["psi_m"] > 0
    np.testing.assert_allclose(mdr["f_perp_N"][growing], cut["f_perp_N"][growing],
                               rtol=2e-3, atol=1e-6)
    assert (mdr["f_perp_N"] > 0).sum() > (cut["f_perp_N"] > 0).sum()
