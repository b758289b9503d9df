"""A sliding-speed ladder in an order the script chooses: the paper's 5 overlaps, and at each
the paper's 4 sliding speeds in a shuffled order (a fixed seed: the same order every run and
on resume). In the paper's order every speed follows the slower ones, so drift of the rig and
the history of earlier passes grow together with the speed; shuffling separates them.

Records the contact search, then one ``speed_ladder`` step per overlap, named
``overlap 0.58 mm``: lift clear, go to the start angle, lower to the overlap, then for each
speed in the shuffled order sweep 16 mm clockwise, wait 60 s, sweep back, wait 60 s. Same
columns and results as the paper's ladder (each result's ``passes`` rows in the order run);
``gelrig analyze`` reports l_g, l_c, the force extremes and mu per overlap and speed.

    gelrig run examples/custom_ladder.py                # the built-in simulated rig
    gelrig plan examples/custom_ladder.py               # rehearse it on the rig's twin
"""

import random

import gelrig

SEED = 17
OVERLAPS = ["0.38 mm", "0.48 mm", "0.58 mm", "0.68 mm", "0.78 mm"]
SPEEDS = ["2.38e-5 m/s", "4.75e-5 m/s", "1.19e-4 m/s", "2.37e-4 m/s"]


def speed_orders(overlaps: list[str], speeds: list[str], seed: int) -> dict[str, list[str]]:
    """Overlap -> its speeds, shuffled; the same seed gives the same orders."""
    rng = random.Random(seed)
    return {overlap: rng.sample(speeds, len(speeds)) for overlap in overlaps}


@gelrig.protocol(rig="shear", name="Shear ladder, speeds in a shuffled order")
def custom_ladder(run: gelrig.Run, overlaps: list[str] = OVERLAPS,
                  speeds: list[str] = SPEEDS, seed: int = SEED) -> None:
    """Find contact, then at each overlap sweep C and AC at the speeds in a shuffled order
    (parameters: ``gelrig run custom_ladder.py --param 'overlaps=["0.78 mm"]'``)."""
    run.step("shear_contact_search", name="contact search", safe_gap="4 mm", coarse="1 mm",
             fine="0.1 mm", rpm=0.5, threshold="0.2 mN*m", sweep="70 mm")
    for overlap, order in speed_orders(overlaps, speeds, seed).items():
        run.log(f"overlap {overlap}: speeds {', '.join(order)}")
        run.step("speed_ladder", name=f"overlap {overlap}", overlaps=1, first_overlap=overlap,
                 speeds=order, travel="16 mm", wait="60 s", interval="0.1 s")


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
