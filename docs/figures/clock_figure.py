"""README figure: one compression run on virtual and on paced:100 time, overlaid (issue 24).

Run: python docs/figures/clock_figure.py  (writes docs/figures/clock_invariance.png)

The short protocol (contact search from 5.6 mm, the paper's 6 % ramp at 0.002 /s, a 60 s hold,
2 mm retract) on the built-in compression rig with the instruments' timing switched on (the
USB-6001's documented 100 ppm drift, 32-sample USB transfers, 1 ms latency and 2 ms jitter;
a 1 ms KDC101 reply latency), through the whole simulated rig. Left: force against plate
position over the ramp-hold-retract step. Right: the recorded force less the contact model's
at the recorded position, against time, in units of the recorded noise.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from gelrig.clock_check import record_short_run, timing_rig
from gelrig.instrument.analysis.contact_residual import model_force
from gelrig.protocols.rigfile import CompressionRigSpec, load_rig

OUT = Path(__file__).with_name("clock_invariance.png")


def main() -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    with tempfile.TemporaryDirectory() as tmp:
        rig = timing_rig(Path(tmp))
        spec = load_rig(rig)
        assert isinstance(spec, CompressionRigSpec)
        for clock, style in (("virtual", dict(color="k", lw=2.5, alpha=0.35)),
                             ("paced:100", dict(color="tab:red", lw=0.8))):
            run = record_short_run(Path(tmp) / clock.replace(":", "_"), clock, rig=rig)
            left.plot(run.position * 1e3, run.force * 1e3, label=clock, **style)  # type: ignore[arg-type]
            res = (run.force - model_force(spec.simulator, run.t, run.position)) / run.noise
            right.plot(run.t - run.t[0], res, ".", ms=1.5, color=style["color"],
                       alpha=0.5 if clock == "virtual" else 0.8,
                       label=f"{clock}: rms {run.residual_rms / run.noise:.2f}")
    left.set(xlabel="plate position (mm)", ylabel="force (mN)",
             title="force against plate position, one run")
    left.legend()
    right.set(xlabel="time in the step (s)", ylabel="recorded - model (noise rms)",
              title="against the contact model at the recorded position", ylim=(-6, 6))
    right.legend(markerscale=6)
    fig.tight_layout()
    fig.savefig(OUT, dpi=110)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
