"""The creep fit of `gelrig analyze` (ADR 0360) over noise seeds, through the whole simulated
compression rig: a contact search and a 150 s creep at 60 mN on the built-in rig with a fast
material (2000 Pa / 60 s, as tests/gelrig/test_analyze_any_run.py), analysed; per seed the
error of G_e, G_1, tau_1 and tau_c in units of its reported standard error, then how many
95 % intervals cover the truth.

Run: python benchmarks/creep_fit_seeds.py [--seeds 20] [--first 1] [--noise "0.2 mN"]
"""

from __future__ import annotations

import argparse
import re
import statistics
import tempfile
from pathlib import Path

import gelrig
from gelrig.analyze_run import analyze_run
from gelrig.protocols.rigfile import default_rig

G_E, G_1, TAU = 7146.0, 2000.0, 60.0
TRUTH = {"G_e": G_E, "G_1": G_1, "tau_1": TAU, "tau_c": TAU * (G_E + G_1) / G_E}


@gelrig.protocol(rig="compression", name="creep")
def creep(run: gelrig.Run) -> None:
    """Find the sphere, hold 60 mN for 150 s."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    run.step("creep", name="creep", force="60 mN", hold="150 s", speed="37 um/s",
             period="1 s", gain=0.5, rate="100 Hz")


def one(seed: int, folder: Path, noise: str = "0.2 mN") -> dict[str, float]:
    """(value - truth) / reported s.e. of each parameter for one seed; ``noise`` the load
    cell's (the rig's 0.2 mN by default)."""
    text = re.sub(r"(?m)^relax = .*$", f'relax = [["{G_1:g} Pa", "{TAU:g} s"]]',
                  default_rig("compression").read_text())
    text = re.sub(r'(?m)^noise = .*$', f'noise = "{noise}"', text, count=1)
    rig = folder / f"rig{seed}.toml"
    rig.write_text(re.sub(r"(?m)^seed = .*$", f"seed = {seed}", text))
    with gelrig.open_rig(rig) as session:
        result = session.run(creep, out=folder / f"run{seed}",
                             sample={"name": "sphere", "diameter": 18.63e-3})
    (hold,) = analyze_run(Path(result.path)).found[1]
    fit = hold.creep
    assert fit is not None
    return {k: (fit.values[k] - t) / fit.stderr[k] for k, t in TRUTH.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first", type=int, default=1)
    parser.add_argument("--noise", default="0.2 mN", help="the load cell's noise (rig: 0.2 mN)")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.first, args.first + args.seeds):
            z = one(seed, Path(tmp), args.noise)
            rows.append(z)
            print(seed, " ".join(f"{k} {v:+.2f}" for k, v in z.items()), flush=True)
    for k in TRUTH:
        z = [r[k] for r in rows]
        print(f"{k}: {sum(abs(v) <= 1.96 for v in z)}/{len(z)} intervals cover the truth; "
              f"error / s.e. mean {statistics.mean(z):+.2f}, sd {statistics.stdev(z):.2f}")


if __name__ == "__main__":
    main()
