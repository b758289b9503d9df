"""A sliding-speed ladder split over steps (``examples/custom_ladder.py``: one
``speed_ladder`` step per overlap, speeds shuffled) on the built-in simulated shear rig, then
``gelrig analyze``: besides one model fit per step, one fit of all passes together, which must
hold the rig's truth (protocols/rigs/shear.toml: G_e 4 kPa, 20 kPa / 2000 s, mu 0.005) inside
its 95 % intervals and be tighter than each step's own fit."""

from __future__ import annotations

from pathlib import Path

import pytest

import gelrig
from gelrig.analyze_run import AnalysisResult, analyze_run

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TRUTH = {"G_e": 4e3, "G_1": 2e4, "tau_1": 2000.0, "mu": 5e-3}
#: two overlaps, three speeds down to the slowest (which tells G_e from G_1)
REDUCED = {"overlaps": ["0.48 mm", "0.78 mm"],
           "speeds": ["2.38e-5 m/s", "1.19e-4 m/s", "2.37e-4 m/s"]}


@pytest.fixture(scope="module")
def split(tmp_path_factory: pytest.TempPathFactory) -> AnalysisResult:
    script = gelrig.load_protocol(EXAMPLES / "custom_ladder.py")
    assert isinstance(script, gelrig.Script)
    out = tmp_path_factory.mktemp("split")
    with gelrig.open_rig("shear") as rig:
        result = rig.run(script.with_params(**REDUCED), out=out / "run")
    assert result.ok, result.reason
    return analyze_run(result.path, out / "analysis")


# The simulated stream can hold two points of one time (see tests/examples/
# test_shear_examples.py): np.gradient then divides by zero at that point.
pytestmark = pytest.mark.filterwarnings(
    "ignore:divide by zero encountered:RuntimeWarning",
    "ignore:invalid value encountered:RuntimeWarning")


def test_the_split_ladder_is_fitted_together(split: AnalysisResult) -> None:
    assert split.complete, split.problems
    assert sorted(split.model_fits) == [1, 2]  # each step's own fit stays
    joint = split.joint_fit
    assert joint is not None
    assert joint.n_passes == sum(len(a.results) for a in split.ladders.values()) == 12
    estimates = {e.name: e for e in joint.estimates}
    for name, truth in TRUTH.items():
        e = estimates[name]
        assert e.lo <= truth <= e.hi, (name, e.value, e.lo, e.hi)
    for fit in split.model_fits.values():  # more passes, a tighter interval than each step's
        own = {e.name: e for e in fit.estimates}
        for name in ("G_e", "G_1", "tau_1"):
            assert estimates[name].hi - estimates[name].lo < own[name].hi - own[name].lo, name
    assert "Joint model fit, ladder steps 1, 2 together (12 passes)" in split.summary
    assert (split.out_dir / "ladder_joint_model_fit.csv").is_file()
