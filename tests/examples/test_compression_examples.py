"""The compression-rig examples (examples/*.py, examples/creep.toml) run on the built-in
simulated rig in virtual time; what they record is checked against the simulator's truth."""

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

import gelrig
from gelrig.cli import main
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.rigfile import default_rig, load_rig

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TRUTH = load_rig(default_rig("compression")).simulator
MDR_RIG = EXAMPLES / "rigs" / "compression_mdr.toml"


#: The sphere of the built-in simulated rig, given as the run's sample (the scripts that need
#: a diameter take it from there; none is assumed).
SPHERE = {"name": "the simulated rig's sphere", "diameter": TRUTH.sphere_diameter}


def run_example(name, out, rig="compression"):
    with gelrig.open_rig(rig) as session:
        result = session.run(EXAMPLES / name, out=out, sample=SPHERE)
    assert result.ok, result.reason
    return result


def by_kind(result, kind):
    return [s for s in result.steps if s["kind"] == kind]


def columns(result, record):
    run = RunDirectory(result.path)
    return run.read_step(int(record["index"]))


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    return run_example("relaxation_series.py", tmp_path_factory.mktemp("series") / "run")


@pytest.fixture(scope="module")
def cycles(tmp_path_factory):
    return run_example("load_unload.py", tmp_path_factory.mktemp("cycles") / "run")


@pytest.fixture(scope="module")
def creep_py(tmp_path_factory):
    return run_example("creep.py", tmp_path_factory.mktemp("creep") / "run")


# -- relaxation series ------------------------------------------------------------------------
def test_series_holds_at_the_asked_strains_with_rests_between(series):
    kinds = [s["kind"] for s in series.steps]
    assert kinds == ["compression_contact_search", "ramp_hold", "rest", "ramp_hold", "rest",
                     "ramp_hold"]
    diameter = TRUTH.sphere_diameter
    for hold, strain in zip(by_kind(series, "ramp_hold"), (0.02, 0.04, 0.06), strict=True):
        results = hold["results"]
        assert results["depth_m"] == pytest.approx(strain * diameter)
        # the overlap measured on the ramp (first touch refitted): within 1 % of the asked one
        assert results["measured_depth_m"] == pytest.approx(strain * diameter, rel=0.01)
        assert results["held_s"] == pytest.approx(600.0, abs=0.1)


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_series_fits_the_simulators_relaxation_time(series):
    (term,) = TRUTH.material.relax
    for hold in by_kind(series, "ramp_hold"):
        fit = hold["results"]["fits"][0]
        tau, err = fit["relax"][0]["tau"], fit["stderr"]["tau_1"]
        assert err < 0.3 * tau, fit  # resolved
        assert abs(tau - term.tau) < 3 * err, (tau, err, term.tau)
        assert fit["G_e"] == pytest.approx(TRUTH.material.g_e, rel=0.05)


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_series_compares_the_fits_across_strains_in_its_log(series):
    log = (series.path / "gelrig.log").read_text()
    lines = [line for line in log.splitlines() if "strain " in line and "G_e = " in line]
    assert [line.split("strain ")[1].split(":")[0] for line in lines] == ["2%", "4%", "6%"]
    (term,) = TRUTH.material.relax
    for line in lines:  # a linear material: the same G_e and tau at every strain
        g_e = float(line.split("G_e = ")[1].split(" kPa")[0]) * 1e3
        assert g_e == pytest.approx(TRUTH.material.g_e, rel=0.05), line
        tau, err = (float(v) for v in line.split("tau = ")[1].removesuffix(" s").split(" +- "))
        assert abs(tau - term.tau) < 3 * err, line


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_series_rests_record_the_baseline_clear_of_the_sphere(series):
    touch = series.results("contact search")["first_touch_m"]
    rests = by_kind(series, "rest")
    assert len(rests) == 2
    for rest in rests:
        r = rest["results"]
        assert r["samples"] == pytest.approx(120 * 100, abs=2)
        assert r["position_m"] <= touch - 2e-3 + 1e-6
        # tared before the hold: the baseline is zero within a few noise levels of its mean
        assert abs(r["force_mean_N"]) < 5 * TRUTH.noise
        assert r["force_sd_N"] == pytest.approx(TRUTH.noise, rel=0.3)


# -- loading-unloading ------------------------------------------------------------------------
def test_cycles_peak_force_rises_with_speed(cycles):
    runs = by_kind(cycles, "load_unload")
    speeds = [s["results"]["speed_m_s"] for s in runs]
    assert speeds == sorted(speeds) and len(set(speeds)) == 3
    peaks = [s["results"]["peak_force_N"] for s in runs]
    # viscoelastic: the slower the cycle, the more the sphere relaxes while loaded
    assert peaks[0] < peaks[1] < peaks[2], peaks
    for s in runs:
        r = s["results"]
        assert r["turn_delta_m"] == pytest.approx(r["depth_m"], abs=0.5e-6)
        assert 0 < r["release_delta_m"] < r["depth_m"]  # let go before the overlap is zero
    assert [s["kind"] for s in cycles.steps].count("rest") == 2


def split(data):
    """(loading, unloading) masks of a cycle's samples: before and after the turn."""
    after = np.arange(data["t_s"].size) > int(data["delta_m"].argmax())
    return ~after, after


def test_unloading_separates_cutoff_from_mdr(cycles, tmp_path):
    mdr = run_example("load_unload.py", tmp_path / "mdr", rig=MDR_RIG)
    assert [s["name"] for s in mdr.steps] == [s["name"] for s in cycles.steps]
    slow_cut, slow_mdr = by_kind(cycles, "load_unload")[0], by_kind(mdr, "load_unload")[0]
    a, b = columns(cycles, slow_cut), columns(mdr, slow_mdr)
    assert (a["t_s"] == b["t_s"]).all() and (a["position_m"] == b["position_m"]).all()
    loading, unloading = split(a)
    diff = abs(a["force_N"] - b["force_N"])
    # the same contact while it grows, the same noise: the loading branches agree (but for
    # the odd sample rounded to the next ADC code)
    assert (diff[loading] > 0).mean() < 0.01 and diff[loading].max() < 2 * TRUTH.noise
    # on the way out, while in contact, the models part: the cutoff lets go sooner
    out = unloading & (a["delta_m"] > 0)
    assert diff[out].mean() > 20 * max(diff[loading].mean(), 1e-9), diff[out].mean()
    assert (slow_cut["results"]["release_delta_m"]
            > slow_mdr["results"]["release_delta_m"] + 2e-6)
    assert slow_cut["results"]["peak_force_N"] == pytest.approx(  # same loading; issue 24's
        slow_mdr["results"]["peak_force_N"], rel=1e-4)  # time base may differ by a few ppm


# -- creep --------------------------------------------------------------------------------------
def sls_creep(delta0, t0, t1):
    """Overlap growth from t0 to t1 under a force applied at t = 0 on a one-term material
    (Hertz: delta^1.5 proportional to the creep compliance J(t))."""
    material = TRUTH.material
    (term,) = material.relax
    g0, ge = material.g_instant, material.g_e
    tau_c = term.tau * g0 / ge

    def compliance(t):
        return 1 / ge - (1 / ge - 1 / g0) * math.exp(-t / tau_c)

    return delta0 * ((compliance(t1) / compliance(t0)) ** (2 / 3) - 1)


def test_creep_holds_the_force_and_the_plate_creeps_forward(creep_py):
    (step,) = by_kind(creep_py, "creep")
    r = step["results"]
    target = r["target_N"]
    assert step["params"]["force"] == pytest.approx(target)
    assert abs(r["force_mean_N"] - target) < 2 * TRUTH.noise
    assert r["force_rms_error_N"] < 3 * TRUTH.noise  # the noise, and little else
    assert r["tolerance_N"] == pytest.approx(2e-3) and r["within_tolerance"] is True
    assert r["force_max_error_N"] < 2e-3
    assert r["held_s"] == pytest.approx(300.0, abs=1.0)
    history = r["history"]
    rises = [b[1] - a[1] for a, b in itertools.pairwise(history)]
    assert sum(d > 0 for d in rises) >= len(rises) - 1, history
    assert r["creep_m"] > 0
    # about as much as a one-term material creeps at that force (ramp: about half its time)
    delta0 = history[0][1]
    ramp = delta0 / step["params"]["speed"]
    expected = sls_creep(delta0, ramp / 2, ramp / 2 + r["held_s"])
    assert 0.5 * expected < history[-1][1] - history[0][1] < 2 * expected, expected


@pytest.mark.slow  # shares a module fixture (a recorded run) with slow tests
def test_creep_recovers_at_rest_after_the_hold(creep_py):
    assert [s["kind"] for s in creep_py.steps] == ["compression_contact_search", "creep", "rest"]
    touch = creep_py.results("contact search")["first_touch_m"]
    r = creep_py.results("recovery")
    assert r["position_m"] == pytest.approx(touch - 2e-3, abs=1e-6)
    assert abs(r["force_mean_N"]) < 5 * TRUTH.noise  # clear of the sphere
    log = (creep_py.path / "gelrig.log").read_text()
    assert "within 2 mN" in log and "creep " in log


def test_creep_toml_equals_creep_py(creep_py, tmp_path, capsys):
    out = tmp_path / "toml"
    assert main(["run", str(EXAMPLES / "creep.toml"), "--out", str(out)]) == 0
    capsys.readouterr()
    meta = RunDirectory(out).read_metadata()
    assert meta["status"] == "completed"
    steps = meta["steps"]
    assert [(s["kind"], s["name"]) for s in steps] == [
        (s["kind"], s["name"]) for s in creep_py.steps]
    for toml_step, py_step in zip(steps, creep_py.steps, strict=True):
        assert toml_step["results"] == py_step["results"]
        assert toml_step["samples"] == py_step["samples"]


# -- refused before anything moves ------------------------------------------------------------
def custom(tmp_path, body):
    path = tmp_path / "p.toml"
    path.write_text('[protocol]\nname = "p"\nrig = "compression"\n'
                    '[sample]\ndiameter = "18.63 mm"\n' + body)
    return path


@pytest.mark.parametrize(("body", "why"), [
    ('[[step]]\nkind = "compression_contact_search"\n'
     '[[step]]\nkind = "creep"\nforce = "3 N"\n', "max_force"),
    ('[[step]]\nkind = "load_unload"\nstrain = 0.04\n', "needs first_touch"),
    ('[[step]]\nkind = "compression_contact_search"\n'
     '[[step]]\nkind = "load_unload"\nstrain = 0.2\n', "max_overlap"),
])
def test_plate_kinds_refuse_before_anything_moves(tmp_path, body, why):
    with gelrig.open_rig("compression") as rig, pytest.raises(gelrig.Refused) as refused:
        rig.run(custom(tmp_path, body), out=tmp_path / "run")
    assert why in str(refused.value) and "refused before anything moves" in str(refused.value)
    assert not (tmp_path / "run").exists()  # nothing recorded


def test_the_paper_compression_script_is_the_protocol_file(tmp_path):
    """examples/paper_compression.py against paper:compression on the same rig and seed:
    the same steps, parameters, results and samples (the 3000 s hold at 1 kHz)."""
    script = run_example("paper_compression.py", tmp_path / "script")
    with gelrig.open_rig("compression") as session:
        toml = session.run("paper:compression", out=tmp_path / "toml")
    assert toml.ok, toml.reason
    assert gelrig.load_protocol(EXAMPLES / "paper_compression.py").name == \
        gelrig.load_protocol("paper:compression").name
    assert [(s["name"], s["kind"]) for s in script.steps] == \
        [(s["name"], s["kind"]) for s in toml.steps] == \
        [("contact search", "compression_contact_search"), ("ramp and hold", "ramp_hold")]
    for ours, theirs in zip(script.steps, toml.steps, strict=True):
        assert ours["params"] == theirs["params"], ours["name"]
        assert ours["results"] == theirs["results"], ours["name"]
        assert ours["samples"] == theirs["samples"] > 0, ours["name"]
    assert script.results("ramp and hold")["fits"][0]["G_e"] > 0
    ours, theirs = columns(script, script.steps[1]), columns(toml, toml.steps[1])
    for column, values in theirs.items():
        np.testing.assert_array_equal(ours[column], values, err_msg=column)
