"""Wall time and quality of the ladder-wide model fit with MDR against the cutoff model.

Run: python benchmarks/bench_ladder_fit_mdr.py [--repeats 3]

Records the reduced paper ladder (0.78 mm, 1.19e-4 and 2.37e-4 m/s, C and AC) on the built-in
simulated shear rig with ``unloading = "mdr"`` (virtual time, a few seconds), then fits it with
each unloading model (docs/decisions/0143). Prints the median wall time of each fit, the MDR
fit's ratio to the cutoff fit (the baseline, measured in the same run), the fitted values
against the rig file's truth and the residuals over the noise.
"""

from __future__ import annotations

import argparse
import copy
import tempfile
from pathlib import Path

from _timing import median_time

from gelrig.analyze_run import _arm, _history, _search_geometry, load_steps
from gelrig.instrument.analysis.ladder_analysis import analyse_ladder_step
from gelrig.instrument.analysis.model_fit import FitSetup, ModelFit, Trajectory, fit_ladder
from gelrig.instrument.core.store import RunDirectory
from gelrig.instrument.physics import paper

SPEEDS = ["1.19e-4 m/s", "2.37e-4 m/s"]


def record(out: Path) -> tuple[RunDirectory, object]:
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.instrument.core.fields import read_toml
    from gelrig.protocols.events import RunState
    from gelrig.protocols.rigfile import default_rig, parse_rig
    from gelrig.protocols.spec import load_protocol, paper_protocol, parse_protocol
    from gelrig.terminal import record_run

    table = copy.deepcopy(read_toml(default_rig("shear"), "rig file"))
    table["simulator"]["unloading"] = "mdr"
    spec = parse_rig(table, "MDR rig")
    proto_table = copy.deepcopy(load_protocol(paper_protocol("shear")).table)
    ladder = proto_table["step"][1]
    first = float(str(ladder["first_overlap"]).split()[0])
    step = float(str(ladder["overlap_step"]).split()[0])
    ladder["first_overlap"] = f"{first + step * (ladder['overlaps'] - 1):.4f} mm"
    ladder["overlaps"], ladder["speeds"] = 1, SPEEDS
    proto = parse_protocol(proto_table, "reduced paper ladder")
    run = RunDirectory.create(out, {"protocol": proto.table, "rig": spec.table})
    state, _ = record_run(proto, spec, VirtualClock(), run, show=False)
    if state is not RunState.COMPLETED:
        raise SystemExit(f"recording ended {state.value}")
    return run, spec.simulator  # type: ignore[attr-defined]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        run, truth = record(Path(tmp) / "run")
        meta, problems = run.read_metadata(), []
        steps = load_steps(run, meta, problems)
        step = next(s for s in steps if s.kind == "speed_ladder")
        arm = _arm(meta, problems)
        ladder = analyse_ladder_step(step.columns, arm)
        touch, angle, _ = _search_geometry(steps, step)
        traj = Trajectory.from_steps(_history(steps, step))
        fits: dict[str, ModelFit] = {}
        times: dict[str, float] = {}
        for model in ("cutoff", "mdr"):
            setup = FitSetup(paper.R1_SHEAR, paper.R2_SHEAR, arm, unloading=model)

            def fit(setup: FitSetup = setup, model: str = model) -> None:
                fits[model] = fit_ladder(traj, ladder.analysis.results, setup, touch, angle)

            times[model] = median_time(fit, args.repeats)
    material = truth.material  # type: ignore[attr-defined]
    print(f"reduced MDR ladder, {len(ladder.analysis.results)} passes; median of "
          f"{args.repeats}; truth G_e {material.g_e:g} Pa, G_1 {material.relax[0].g:g} Pa, "
          f"tau_1 {material.relax[0].tau:g} s, mu {truth.mu:g}")  # type: ignore[attr-defined]
    for model, f in fits.items():
        values = ", ".join(f"{n} {f.estimate(n).value:.4g}" for n in ("G_e", "G_1", "tau_1", "mu"))
        ratio = ("" if model == "cutoff"
                 else f"   ratio to cutoff {times[model] / times['cutoff']:.1f}")
        print(f"  {model:6s} fit {times[model]:7.3f} s{ratio}; {values}; rms/noise F_h "
              f"{f.rms_h / f.noise_h:.2f}, F_v {f.rms_v / f.noise_v:.2f}; "
              f"{f.evaluations} evaluations")


if __name__ == "__main__":
    main()
