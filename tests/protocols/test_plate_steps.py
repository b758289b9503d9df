"""The built-in plate steps (``move``, ``wait``, ``rest``, ``load_unload``, ``creep``) and
``repeat`` in a protocol file, through the whole simulated compression rig in virtual time:
what they record is checked against the contact physics (physics.md 1) and the simulator's
material."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

import gelrig
from gelrig.cli import main
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.control import RunControl
from gelrig.protocols.events import EventBus, StepStarted
from gelrig.protocols.host import RunHost, create_run
from gelrig.protocols.rigfile import default_rig, load_rig

TRUTH = load_rig(default_rig("compression")).simulator
HEAD = ('[protocol]\nname = "blocks"\nrig = "compression"\n'
        f'[sample]\ndiameter = "{TRUTH.sphere_diameter * 1e3:g} mm"\n'
        '[[step]]\nkind = "compression_contact_search"\nname = "contact search"\n'
        'speed = "0.3 mm/s"\n')
#: the built-in rig's first touch ([simulator] first_touch): where "into" moves the plate to
TOUCH = 6.2e-3
BLOCKS = HEAD + '''
[[step]]
kind = "move"
name = "back"
by = "-0.5 mm"
speed = "0.5 mm/s"

[[step]]
kind = "wait"
name = "clear"
duration = "20 s"

[[step]]
kind = "move"
name = "into"
to = "6.5 mm"
speed = "0.5 mm/s"

[[step]]
kind = "wait"
name = "pressed"
duration = "120 s"

[[step]]
kind = "rest"
name = "rest"
duration = "30 s"
clear = "1 mm"

[[step]]
kind = "load_unload"
name = "to 50 mN"
to_force = "50 mN"
speed = "20 um/s"
cycles = 3

[[step]]
kind = "load_unload"
name = "strain"
strain = 0.03
speed = "50 um/s"
repeat = 2

[[step]]
kind = "creep"
name = "creep"
force = "50 mN"
hold = "60 s"
tolerance = "1 mN"
period = "1 s"

[[step]]
kind = "creep"
name = "too tight"
force = "50 mN"
hold = "20 s"
tolerance = "0.001 mN"
period = "1 s"
'''


def write(tmp_path: Path, text: str, name: str = "p.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def g(t: float) -> float:
    """The simulator's relaxation modulus G(t) (Pa)."""
    m = TRUTH.material
    return m.g_e + sum(term.g * math.exp(-t / term.tau) for term in m.relax)


def hertz_overlap(force: float, modulus: float) -> float:
    """Overlap (m) at which the plate-sphere contact carries ``force`` (physics.md 1)."""
    k = 4 * math.sqrt(TRUTH.sphere_diameter / 2) / (3 * (1 - 0.5))
    return (force / (k * modulus)) ** (2 / 3)


@pytest.fixture(scope="module")
def blocks(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("blocks")
    with gelrig.open_rig("compression") as rig:
        result = rig.run(write(tmp, BLOCKS), out=tmp / "run")
    assert result.ok, result.reason
    return result


def data(result, name):
    step = next(s for s in result.steps if s["name"] == name)
    return RunDirectory(result.path).read_step(int(step["index"]))


def test_the_kinds_are_built_in_and_repeat_expands_the_sequence(blocks):
    assert [(s["kind"], s["name"]) for s in blocks.steps][-5:] == [
        ("load_unload", "to 50 mN"), ("load_unload", "strain 1"),
        ("load_unload", "strain 2"), ("creep", "creep"), ("creep", "too tight")]
    assert {"wait", "move", "rest", "load_unload", "creep"} <= set(gelrig.step_kinds())


def test_move_ends_where_it_was_sent_recording_the_force(blocks):
    start = blocks.results("contact search")["first_touch_m"]
    back, into = blocks.results("back"), blocks.results("into")
    assert back["end_position_m"] == pytest.approx(back["start_position_m"] - 0.5e-3, abs=1e-6)
    assert back["target_m"] == pytest.approx(back["start_position_m"] - 0.5e-3)
    assert 1.0 < back["duration_s"] < 1.4  # 0.5 mm at 0.5 mm/s, with its acceleration
    assert abs(back["force_end_N"]) < 5 * TRUTH.noise  # clear of the sphere
    assert into["end_position_m"] == pytest.approx(6.5e-3, abs=1e-6)
    cols = data(blocks, "into")
    assert cols["position_m"][-1] == pytest.approx(6.5e-3, abs=1e-6)
    # pressed ~0.3 mm into the sphere: about the Hertz force at the instantaneous modulus
    delta = 6.5e-3 - start
    k = 4 * math.sqrt(TRUTH.sphere_diameter / 2) / 1.5
    assert into["force_end_N"] == pytest.approx(k * g(0.0) * delta ** 1.5, rel=0.05)
    assert np.all(np.diff(cols["force_N"][cols["delta_m"] > 20e-6]) > -5 * TRUTH.noise)


def test_wait_holds_the_stage_and_records_the_force_relaxing(blocks):
    clear, pressed = blocks.results("clear"), blocks.results("pressed")
    for r, seconds in ((clear, 20.0), (pressed, 120.0)):
        assert r["position_span_m"] < 1e-9  # nothing moved
        assert r["samples"] == pytest.approx(seconds * 100, abs=2)
        assert r["duration_s"] == pytest.approx(seconds, abs=0.05)
    assert abs(clear["force_mean_N"]) < 5 * TRUTH.noise and abs(clear["force_drift_N"]) < 0.1e-3
    # under a fixed overlap the force follows G(t): it relaxes by about G(t)'s drop over the
    # wait (the move took ~0.6 s: t from the middle of that ramp)
    cols = data(blocks, "pressed")
    t = cols["t_s"] - data(blocks, "into")["t_s"][-1] + 0.3
    tenth = t.size // 10
    ratio = g(t[-tenth:].mean()) / g(t[:tenth].mean())
    expected = pressed["force_mean_N"] * (ratio - 1)
    assert pressed["force_drift_N"] < 0
    assert pressed["force_drift_N"] == pytest.approx(expected, rel=0.3), expected


def test_rest_backs_off_and_records_the_baseline(blocks):
    touch = blocks.results("contact search")["first_touch_m"]
    r = blocks.results("rest")
    assert r["position_m"] == pytest.approx(touch - 1e-3, abs=1e-6)
    assert abs(r["force_mean_N"]) < 5 * TRUTH.noise
    assert r["force_sd_N"] == pytest.approx(TRUTH.noise, rel=0.3)


def test_load_unload_to_force_turns_at_the_force_three_times(blocks):
    r = blocks.results("to 50 mN")
    assert math.isnan(r["depth_m"]) and r["to_force_N"] == pytest.approx(0.05)
    cycles = r["cycles"]
    assert len(cycles) == 3
    assert cycles[0]["start_index"] == 0
    for a, b in itertools.pairwise(cycles):
        assert b["start_index"] == a["end_index"]  # one after the other
    assert cycles[-1]["end_index"] == r["samples"]
    # the deepest overlap: where Hertz carries 50 mN, between the instantaneous modulus's
    # and the relaxed one's (a ~45 s ramp)
    lo, hi = hertz_overlap(0.05, g(0.0)), hertz_overlap(0.05, TRUTH.material.g_e)
    cols = data(blocks, "to 50 mN")
    for c in cycles:
        assert c["peak_force_N"] == pytest.approx(0.05, rel=0.03), c
        force = cols["force_N"][c["start_index"]:c["end_index"]]
        assert force.max() == pytest.approx(0.05, abs=1e-3)  # stopped at once on the crossing
        assert 0.98 * lo < c["turn_delta_m"] < 1.02 * hi, (lo, c, hi)
        assert c["hysteresis_J"] > 0  # viscoelastic: energy lost in every cycle
    assert r["peak_force_N"] == cycles[0]["peak_force_N"]


def test_load_unload_at_a_strain_turns_at_its_depth(blocks):
    for name in ("strain 1", "strain 2"):
        r = blocks.results(name)
        assert r["depth_m"] == pytest.approx(0.03 * TRUTH.sphere_diameter)
        assert r["turn_delta_m"] == pytest.approx(r["depth_m"], abs=0.5e-6)
        assert len(r["cycles"]) == 1 and r["cycles"][0]["turn_index"] == r["turn_index"]


def test_creep_holds_the_force_within_its_tolerance_and_the_plate_creeps_in(blocks):
    r = blocks.results("creep")
    assert r["within_tolerance"] is True and r["tolerance_N"] == pytest.approx(1e-3)
    assert r["force_max_error_N"] <= 1e-3
    assert r["force_rms_error_N"] < 3 * TRUTH.noise
    # the modulus relaxes, so holding the force needs more overlap: the plate moves in
    assert r["creep_m"] > 0
    depths = [d for _, d in r["history"]]
    assert depths[-1] > depths[0]
    tight = blocks.results("too tight")  # the same hold cannot stay within 1 uN
    assert tight["within_tolerance"] is False
    assert tight["force_max_error_N"] > 1e-6


def test_plan_prints_the_expanded_steps(tmp_path, capsys):
    path = write(tmp_path, HEAD + '[[step]]\nkind = "wait"\nname = "settle"\nduration = "5 s"'
                 '\nrepeat = 3\n[[step]]\nkind = "creep"\nforce = "20 mN"\nhold = "10 s"\n')
    assert main(["plan", str(path)]) == 0
    out = capsys.readouterr().out
    for n in (1, 2, 3):
        assert f"{n}. settle {n} [wait]" in out
    assert "4. creep at constant force [creep]" in out
    assert "hold 20 mN +- 2 mN for 10 s" in out


@pytest.mark.parametrize(("body", "why"), [
    ('[[step]]\nkind = "load_unload"\nspeed = "20 um/s"\n',
     '[step[1]] to_force = "missing": give where to turn: strain, depth or to_force'),
    ('[[step]]\nkind = "load_unload"\nstrain = 0.02\nto_force = "20 mN"\n',
     "give either to_force or an overlap"),
    ('[[step]]\nkind = "load_unload"\nstrain = 0.02\ndepth = "1 mm"\n',
     "contradicts strain 0.02 x diameter 18.63 mm"),
    ('[[step]]\nkind = "load_unload"\nto_force = "3 N"\n',
     "to_force 3000 mN >= force limit 2000 mN"),
    ('[[step]]\nkind = "move"\nto = "24 mm"\nspeed = "0.5 mm/s"\n', "beyond the stage's travel"),
    ('[[step]]\nkind = "move"\nby = "1 mm"\nspeed = "9 mm/s"\n',
     '[step[1]] speed = "9 mm/s": allowed (0, 2.6] mm/s'),
    ('[[step]]\nkind = "move"\nspeed = "1 mm/s"\n', "give exactly one of to"),
    ('[[step]]\nkind = "wait"\nduration = "5 s"\nrepeat = 0\n',
     "[step[1]] repeat = 0: an integer in [1, 1000]"),
])
def test_bad_blocks_are_refused_before_anything_moves_exit_2(tmp_path, capsys, body, why):
    path = write(tmp_path, HEAD + body)
    assert main(["run", str(path), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and why in err[0], err
    assert not (tmp_path / "run").exists()


def test_a_run_of_repeated_steps_resumes_through_them(tmp_path):
    path = write(tmp_path, HEAD + '[[step]]\nkind = "wait"\nname = "settle"\nduration = "5 s"'
                 '\nrepeat = 3\n')
    with gelrig.open_rig("compression") as session:
        procedure = gelrig.load_protocol(path)
        run = create_run(procedure, session.spec, session.clock_spec, tmp_path / "run")
        control, bus = RunControl(), EventBus()
        bus.subscribe(lambda e: control.abort("test abort") if isinstance(e, StepStarted)
                      and e.name == "settle 2" else None)
        with RunHost(session.rig, procedure, run, bus=bus, control=control) as host:
            assert host.run().value == "aborted"
        first = run.read_metadata()["steps"]
        assert [s["status"] for s in first][:2] == ["completed", "completed"]
        result = session.resume(tmp_path / "run")
    assert result.ok, result.reason
    assert [s["name"] for s in result.steps] == ["contact search", "settle 1", "settle 2",
                                                 "settle 3"]
    assert result.steps[1]["started"] == first[1]["started"]  # not run again
    # 5 s at 100 Hz each, none of the resume's backlog in the first one that runs again
    assert all(abs(s["results"]["samples"] - 500) <= 1 for s in result.steps[1:]), \
        [s["results"]["samples"] for s in result.steps]


def test_shear_wait_holds_the_arm_and_records_the_stream(tmp_path):
    path = write(tmp_path, '[protocol]\nname = "w"\nrig = "shear"\n[[step]]\n'
                 'kind = "shear_wait"\nname = "quiet"\nduration = "30 s"\ninterval = "50 ms"\n')
    with gelrig.open_rig("shear") as rig:
        result = rig.run(path, out=tmp_path / "run")
    assert result.ok, result.reason
    r = result.results("quiet")
    assert r["duration_s"] == pytest.approx(30.0, abs=0.05)
    assert abs(r["samples"] - 600) <= 1 and r["angle_span_rad"] == 0.0
    cols = RunDirectory(result.path).read_step(0)
    assert cols["t_s"].size == r["samples"]
    assert np.all(np.diff(cols["t_s"]) == pytest.approx(0.05))  # every point, none lost
    assert abs(r["torque_mean_Nm"]) < 3 * r["torque_sd_Nm"]  # nothing touches: noise only


@pytest.mark.parametrize("kind", ["wait", "move", "rest", "load_unload", "creep", "shear_wait"])
def test_every_field_of_a_block_has_a_unit_a_range_and_help(kind):
    from gelrig.protocols.steps import BUILT_IN, KINDS

    assert kind in BUILT_IN
    definition = KINDS[kind]
    assert definition.__doc__ and definition.Result.__doc__
    for f in definition.fields:
        assert f.help, (kind, f.key)
        assert math.isfinite(f.lo) and math.isfinite(f.hi), (kind, f.key)
        assert f.unit or f.key in ("strain", "gain", "cycles"), (kind, f.key)
