"""The same contact on every clock: first touch, depth and model residual against virtual.

Run: python benchmarks/bench_clocks.py [--clocks virtual,paced:20,paced:100,real] [--hold "60 s"]
[--timing] [--updates] [--noise "0.05 mN"] [--seed 1]

Runs the short compression protocol of issue 24 (contact search from 5.6 mm, the paper's 6 %
ramp at 0.002 /s, a hold, 2 mm retract) through the whole simulated rig (simulator, wire,
driver, runner, recorder) on each clock and prints, against the virtual run: the contact
search's first touch, the ramp's refitted first touch, the measured depth, and the recorded
force against the contact model at the recorded plate position (rms and worst, in units of
the recorded noise, which includes the ADC's quantization) over the whole ramp-hold-retract
step, and how many samples had their position flagged. ``--timing`` switches the instruments'
timing on (the USB-6001's documented drift, USB transfers, latency and jitter; a 1 ms KDC101
reply latency). ``--updates`` has the stage driver take the KDC101's status updates as
position reports (ADR 0243). A second table prints, per clock, how often the stage was
reported in lab time and within what window, polls and updates (run.json's
``time_base.stage``). A real clock runs the protocol in real time (about 2.5 minutes).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from gelrig.clock_check import ClockRun, record_short_run, timing_rig
from gelrig.protocols.rigfile import default_rig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clocks", default="virtual,paced:20,paced:100")
    ap.add_argument("--hold", default="60 s")
    ap.add_argument("--timing", action="store_true", help="drift and latency on")
    ap.add_argument("--updates", action="store_true",
                    help="status updates as position reports (ADR 0243)")
    ap.add_argument("--noise", default=None, help="the rig's force noise (default 0.2 mN)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    runs: dict[str, ClockRun] = {}
    with tempfile.TemporaryDirectory() as tmp:
        rig = (timing_rig(Path(tmp), args.seed, noise=args.noise, updates=args.updates)
               if args.timing
               else timing_rig(Path(tmp), args.seed, noise=args.noise, stage_latency=0.0,
                               daq=False, updates=args.updates))
        print(f"rig: {default_rig('compression').name}, timing {'on' if args.timing else 'off'}"
              f", noise {args.noise or '0.2 mN'}, seed {args.seed}")
        for i, clock in enumerate(args.clocks.split(",")):
            runs[clock] = record_short_run(Path(tmp) / f"run{i}", clock, hold=args.hold,
                                           rig=rig)
    ref = runs.get("virtual") or next(iter(runs.values()))
    print(f"{'clock':<12s} {'search touch':>14s} {'ramp touch':>12s} {'depth':>9s} "
          f"{'resid rms':>10s} {'worst':>8s} {'flagged':>8s}")
    for clock, r in runs.items():
        print(f"{clock:<12s} {(r.search_touch - ref.search_touch) * 1e6:+11.2f} um "
              f"{(r.ramp_touch - ref.ramp_touch) * 1e6:+9.2f} um "
              f"{(r.depth / ref.depth - 1) * 100:+7.3f} % "
              f"{r.residual_rms / r.noise:8.2f} sd {r.residual_worst / r.noise:6.2f} sd "
              f"{r.flagged:8d}")
    print(f"\n{'clock':<12s} {'reports':>8s} {'interval':>10s} {'window':>9s} "
          f"{'updates':>8s} {'interval':>10s} {'window':>9s}  (medians, lab time)")
    for clock, r in runs.items():
        d = r.time_base["stage"]["details"]
        nan = float("nan")
        print(f"{clock:<12s} {d['reports_kept']:8d} {d['report_interval_median_s']:8.3f} s "
              f"{d['report_window_median_s'] * 1e3:6.1f} ms {d['updates_kept']:8d} "
              f"{d['update_interval_median_s'] or nan:8.3f} s "
              f"{(d['update_window_median_s'] or nan) * 1e3:6.1f} ms")


if __name__ == "__main__":
    main()
