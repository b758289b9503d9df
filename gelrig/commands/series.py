"""``gelrig series RUN_DIR [RUN_DIR ...]``: every hold of the runs compared (tau, G_e, G_1
against strain and hold length, with 95 % intervals) in a table, a figure and a CSV."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    series = sub.add_parser("series", help="compare the holds of one or more runs")
    series.add_argument("run_dirs", metavar="RUN_DIR", nargs="+")
    series.add_argument("--out", default="series",
                        help="report folder (default ./series): series.csv, series.png, "
                             "report.html, and each run's analysis under runs/")
    series.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from gelrig.series_run import series_report

    result = series_report(args.run_dirs, args.out)
    print(result.summary)
    return 0
