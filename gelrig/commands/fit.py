"""``gelrig fit relaxation FILE.csv``: the hold's Prony fit as JSON on stdout.

The JSON holds the fit with as many terms as the data resolve (``terms_resolved``; the fit as
requested is under ``unresolved_fit`` then, and ``not_resolved`` says why, also on stderr).
``resolved`` says whether the reported fit is a result: when not even one term is resolved
(ADR 0261) the JSON has no values at its top level, only ``resolved: false``, the reason and
``unresolved_fit`` (not a result). An undetermined standard error is ``null``.
"""

from __future__ import annotations

import argparse
import json
import sys

from gelrig.commands._args import poisson, quantity


def register(sub: argparse._SubParsersAction) -> None:
    fit = sub.add_parser("fit", help="fit recorded or modelled data")
    which = fit.add_subparsers(dest="fit", metavar="WHAT")
    which.required = True
    relax = which.add_parser("relaxation", help="Prony fit of G(t) over the hold of a CSV")
    relax.add_argument("file", metavar="FILE.csv", help="columns t_s,force_N (and delta_m)")
    relax.add_argument("--radius", required=True, type=quantity("m"), help="sphere radius (m)")
    relax.add_argument("--depth", required=True, type=quantity("m"), help="hold overlap (m)")
    relax.add_argument("--nu", type=poisson, default=0.5, help="Poisson ratio (default 0.5)")
    relax.add_argument("--terms", type=int, choices=(1, 2), default=1,
                       help="relaxation terms to try (default 1); a term the data do not "
                            "resolve is not reported")
    relax.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from gelrig.instrument.analysis.relaxation import fit_hold
    from gelrig.instrument.core.csvio import read_columns

    cols = read_columns(args.file, ["t_s", "force_N"], ["delta_m"])
    fit = fit_hold(cols["t_s"], cols["force_N"], args.radius, args.depth, args.nu, args.terms,
                   delta=cols.get("delta_m"))
    print(json.dumps(fit.as_result(), indent=2))
    if not fit.resolved.is_resolved:
        print(f"gelrig fit: not resolved: {fit.resolved.reason}; no result", file=sys.stderr)
    elif fit.not_resolved:
        print(f"gelrig fit: {fit.not_resolved}; reporting {len(fit.resolved.relax)} term(s)",
              file=sys.stderr)
    return 0
