"""``gelrig analyze RUN_DIR``: a run's figures, tables and model fit as an HTML report."""

from __future__ import annotations

import argparse
import sys

from gelrig.commands._args import quantity


def register(sub: argparse._SubParsersAction) -> None:
    analyze = sub.add_parser(
        "analyze", help="analyse a run directory into an HTML report",
        description="Analyse a run of any steps: every step's columns drawn, every hold found "
                    "(relaxation: the plate still; creep: the force held) and fitted, ramp_hold "
                    "and speed_ladder steps as the paper's, several ladder steps also fitted "
                    "together. To compare holds across runs: gelrig series.")
    analyze.add_argument("run_dir", metavar="RUN_DIR")
    analyze.add_argument("--out", default=None, help="report folder (default RUN_DIR/analysis)")
    # Defaults None, resolved by analyze_run: the run's sample (run.json), else the paper's.
    analyze.add_argument("--r1", type=quantity("m"), default=None,
                         help="shear rig: upper sphere radius (default: the run's sample's; "
                              "a run without one: the paper's 9.2 mm, said in the problems)")
    analyze.add_argument("--r2", type=quantity("m"), default=None,
                         help="shear rig: lower sphere radius (default: the run's sample's; "
                              "a run without one: the paper's 9.96 mm, said in the problems)")
    analyze.add_argument("--terms", type=int, choices=(1, 2), default=1,
                         help="relaxation terms of the shear model fit (default 1)")
    analyze.add_argument("--no-model-fit", action="store_true",
                         help="skip the ladder-wide model fit")
    analyze.add_argument("--fixed-geometry", action="store_true",
                         help="hold the contact search's touch gap and lower-sphere angle fixed "
                              "in the model fit instead of refining them")
    # The names of gelrig.instrument.physics.contact.UNLOADING_MODELS, spelt out: the parser stays
    # light.
    analyze.add_argument("--unloading", choices=("cutoff", "mdr"), default="cutoff",
                         help="unloading model of the shear model fit: cutoff (the paper's "
                              "no-adhesion cutoff, default) or mdr (dimensionality reduction, "
                              "docs/decisions/0150)")
    analyze.add_argument("--anisotropic", action="store_true",
                         help="fit the relaxation moduli G_i separately for F_h and F_v (the "
                              "paper's anisotropy, docs/decisions/0142); default: one set")
    analyze.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from gelrig.analyze_run import analyze_run

    result = analyze_run(args.run_dir, args.out, r1=args.r1, r2=args.r2, terms=args.terms,
                         fit_model=not args.no_model_fit, fit_geometry=not args.fixed_geometry,
                         unloading=args.unloading, anisotropic=args.anisotropic)
    print(result.summary)
    if result.problems:
        print(f"gelrig: warning: {args.run_dir} is incomplete; analysed what is there "
              f"({len(result.problems)} problem(s), listed above and in the report)",
              file=sys.stderr)
    return 0
