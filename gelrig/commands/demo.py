"""``gelrig demo``: the paper's two protocols on the simulated rigs, then the analysis.

Runs the paper's compression and shear protocols on the built-in simulated rigs in virtual
time (every byte through the real drivers), records them, summarises what they found, and
adds the model's reference curves (the paper's numbers, fitted and plotted).
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the model, numpy and matplotlib are imported when the command runs
    import numpy as np

    from gelrig.instrument.physics.contact import Material

#: Load-cell noise added to the modelled holds (N, 1 sigma), about the USB-6001's 14-bit step
#: through the default load-cell chain; seeded, so every demo run is identical.
FORCE_NOISE = 2e-4


def register(sub: argparse._SubParsersAction) -> None:
    demo = sub.add_parser("demo", help="both paper protocols on the simulated rigs, analysed")
    demo.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    demo.add_argument("--seed", type=int, default=1, help="noise seed of the model part")
    demo.add_argument("--no-runs", action="store_true",
                      help="skip the simulated runs; only the model reference")
    demo.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary: dict[str, object] = {}
    reports: dict[str, str] = {}
    if not args.no_runs:
        summary["runs"] = runs = _runs(out / "runs")
        summary["reports"] = reports = _analyse(runs)
    rng = np.random.default_rng(args.seed)
    print("\nModel reference (the paper's parameters): the contact model evaluated at the true "
          "parameters, no rig. It may differ from the analyses above, which see only the "
          "recorded data: noise, a first touch and touch gap the protocol had to find, the "
          "run's own overlaps, holds and speeds, and the simulated contact's history.")
    model = out / "model"
    model.mkdir(exist_ok=True)
    summary["model"] = {"compression": _compression(model, rng), "shear": _shear(model)}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(f"\nwrote runs, CSV, PNG and summary.json to {out.resolve()}")
    for kind, report in reports.items():
        print(f"  {kind} report: {report}")
    return 0


#: One line each on what the analysis tables are and why they may differ from the reference.
_WHAT = {
    "compression": "gelrig analyze on the recorded data (hidden truth: the rig file's "
                   "[simulator], G_e 7146 Pa, 630 Pa / 1413 s, first touch 6.2 mm); it "
                   "differs from the truth by the noise and the first touch it had to find",
    "shear": "gelrig analyze on the recorded data: measured l_g beside the chord at the set "
             "overlap, l_c/l_g and mu; differs from the model reference below by the "
             "ladder's overlaps and searched touch gap, the noise and the simulator's contact "
             "history",
}


def _analyse(runs: dict[str, object]) -> dict[str, str]:
    """Analyse each recorded run into its HTML report; print the one-screen summaries."""
    from gelrig.analyze_run import analyze_run

    reports = {}
    for kind, info in runs.items():
        assert isinstance(info, dict)
        result = analyze_run(Path(info["run_dir"]))
        print(f"\n== analysis of the {kind} run: {_WHAT[kind]}\n{result.summary}")
        reports[kind] = str(result.report_path)
    return reports


def _runs(folder: Path) -> dict[str, object]:
    """Both paper protocols on the built-in simulated rigs, in virtual time."""
    from gelrig.commands.run import summarise
    from gelrig.factory import build_rig
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.protocols.host import RunHost, closing_rig, create_run
    from gelrig.protocols.resolve import resolve_procedure, resolve_rig
    from gelrig.terminal import run_in_terminal

    found: dict[str, object] = {}
    for kind in ("compression", "shear"):
        protocol = resolve_procedure(f"paper:{kind}")
        rig = resolve_rig(None, protocol)
        target = folder / kind
        if (target / "run.json").exists():
            shutil.rmtree(target)
        print(f"\n== {protocol.name}\n   on {rig.name}, virtual time, recording to {target}")
        t0 = time.perf_counter()
        with closing_rig(build_rig(rig, VirtualClock())) as built:
            run_dir = create_run(protocol, rig, "virtual", target)
            with RunHost(built, protocol, run_dir) as host:
                state = run_in_terminal(host)
        wall = time.perf_counter() - t0
        summarise(run_dir, state, host.reason)
        lab = sum(float(s.get("finished") or 0) - float(s.get("started") or 0)
                  for s in run_dir.read_metadata()["steps"])
        print(f"   {lab:,.0f} s of lab time in {wall:.1f} s of wall time")
        found[kind] = {"state": state.value, "run_dir": str(target), "wall_s": wall,
                       "results": {str(k): v for k, v in host.runner.results.items()}}
    return found


def _compression(out: Path, rng: np.random.Generator) -> dict[str, object]:
    from gelrig.instrument.analysis.relaxation import fit_hold, modulus_history
    from gelrig.instrument.core.csvio import write_columns
    from gelrig.instrument.physics import paper
    from gelrig.instrument.physics.compression import ramp_hold
    from gelrig.instrument.reports.plots import plot_force, plot_relaxation

    radius, depth = paper.R_COMPRESSION, paper.DEPTH_HOLD
    print(f"Compression: sphere {paper.DIAMETER_COMPRESSION * 1e3:.2f} mm, ramp to "
          f"{depth * 1e3:.3f} mm at {paper.RAMP_SPEED * 1e6:.1f} um/s, hold {paper.HOLD:.0f} s "
          f"at 100 Hz, noise {FORCE_NOISE * 1e3:.1f} mN")
    print("  (the model's ramp and hold at the true parameters plus seeded noise, fitted back: "
          "how closely the fit recovers a known truth)")
    results: dict[str, object] = {}
    panels = []
    for name, material, terms in (("plates", paper.PLATES, (1, 2)),
                                  ("shell", paper.SHELL, (1, 2))):
        rec = ramp_hold(radius, depth, paper.RAMP_SPEED, paper.HOLD, material, dt=0.01)
        force = rec.force + rng.normal(0.0, FORCE_NOISE, rec.force.size)
        write_columns(out / f"compression_{name}.csv",
                      {"t_s": rec.t, "delta_m": rec.delta, "force_N": force})
        fits = [fit_hold(rec.t, force, radius, depth, terms=n, delta=rec.delta) for n in terms]
        hold = rec.t >= fits[0].t0
        t_hold = rec.t[hold] - fits[0].t0
        panels.append((f"{name}: {_describe(material)}", t_hold,
                       modulus_history(force[hold], depth, radius), fits))
        plot_force(out / f"compression_{name}_force.png", rec.t, force,
                   f"ramp and hold ({name})")
        results[name] = {"true": _material_dict(material), "fits": [f.as_dict() for f in fits]}
        for fit in fits:
            if not fit.is_resolved:  # not a result: say why, not its values
                stands = fit.resolved
                print(f"  {name:6s} {len(fit.relax)}-term fit: not resolved: {fit.reason}"
                      + (f" (the {len(stands.relax)}-term fit stands)"
                         if stands is not fit and stands.is_resolved else ""))
                continue
            taus = ", ".join(f"G {r.g:7.1f} Pa tau {r.tau:7.1f} s" for r in fit.relax)
            print(f"  {name:6s} {len(fit.relax)}-term fit: G_e {fit.g_e:8.1f} Pa, {taus}; "
                  f"rmse {fit.rmse:.1f} Pa   (true: {_describe(material)})")
    plot_relaxation(out / "compression_relaxation.png", panels)
    return results


def _shear(out: Path) -> dict[str, object]:
    from gelrig.instrument.analysis.relaxation import contact_length
    from gelrig.instrument.core.csvio import write_columns
    from gelrig.instrument.physics import paper
    from gelrig.instrument.physics.sliding import SlidingGeometry, rpm_from_speed, shear_pass
    from gelrig.instrument.reports.plots import plot_passes

    geometry = SlidingGeometry(paper.R1_SHEAR, paper.R2_SHEAR, paper.DELTA_MAX_SHOWN)
    print(f"\nShear: R1 {paper.R1_SHEAR * 1e3:.2f} mm over R2 {paper.R2_SHEAR * 1e3:.2f} mm, "
          f"delta_max {paper.DELTA_MAX_SHOWN * 1e3:.2f} mm, mu {paper.MU:g}, "
          f"l_g {geometry.l_g * 1e3:.3f} mm (the chord)")
    print("  (one fresh pass of the model at the paper's fitted parameters and exact geometry: "
          "the reference for the analysed ladder)")
    print(f"  {'speed (m/s)':>12s} {'rpm':>8s} {'F_h peak':>9s} {'trough':>9s} {'F_v peak':>9s}"
          f" {'l_c (mm)':>9s} {'l_c/l_g':>8s}")
    rows = []
    passes = []
    for speed in paper.SPEEDS:
        h_pass = shear_pass(geometry, paper.SHEAR_FH, speed, paper.MU, margin=0.2e-3)
        v_pass = shear_pass(geometry, paper.SHEAR_FV, speed, paper.MU, margin=0.2e-3)
        l_c = contact_length(h_pass.theta, h_pass.f_perp)
        write_columns(out / f"shear_{speed:.3g}.csv", {
            "t_s": h_pass.t, "psi_m": h_pass.psi, "delta_m": h_pass.delta,
            "f_perp_N": h_pass.f_perp, "f_h_N": h_pass.f_h, "f_v_N": v_pass.f_v})
        passes.append((f"{speed:.3g} m/s", h_pass.theta, h_pass.f_h, v_pass.f_v))
        row = {"speed_m_s": speed, "rpm": rpm_from_speed(speed, paper.ARM),
               "f_h_peak_N": float(h_pass.f_h.max()), "f_h_trough_N": float(h_pass.f_h.min()),
               "f_v_peak_N": float(v_pass.f_v.max()), "l_c_m": l_c, "l_g_m": geometry.l_g}
        rows.append(row)
        print(f"  {speed:12.3g} {row['rpm']:8.4f} {row['f_h_peak_N'] * 1e3:7.3f}mN "
              f"{row['f_h_trough_N'] * 1e3:7.3f}mN {row['f_v_peak_N'] * 1e3:7.2f}mN "
              f"{l_c * 1e3:9.3f} {l_c / geometry.l_g:8.4f}")
    plot_passes(out / "shear_passes.png", passes,
                f"one pass at delta_max {paper.DELTA_MAX_SHOWN * 1e3:.2f} mm (F_h: G_l = 5 G_e; "
                "F_v: G_l = 4 G_e)")
    return {"delta_max_m": paper.DELTA_MAX_SHOWN, "l_g_m": geometry.l_g, "passes": rows}


def _describe(material: Material) -> str:
    terms = ", ".join(f"{r.g:.0f} Pa/{r.tau:.0f} s" for r in material.relax)
    return f"G_e {material.g_e:.0f} Pa, {terms}"


def _material_dict(material: Material) -> dict[str, object]:
    return {"G_e": material.g_e, "relax": [{"G": r.g, "tau": r.tau} for r in material.relax]}
