"""Loading-unloading cycles at three rates: find first touch, then ramp into the sphere to 4 %
of its diameter and straight back out at 1, 10 and 100 um/s (the built-in ``load_unload``),
with the plate backed off and the force recorded for 60 s between cycles (``rest``). Records
one step per cycle (force, position and overlap columns; results: peak force, where the force
is gone on the way out, the energy lost).

The unloading branch is the data that separates the paper's cutoff unloading model from a
recovery-consistent one (MDR, physics.md 1b): run it on ``examples/rigs/compression_mdr.toml``
to see the difference on the way out while the loading branch stays the same.

The sphere's diameter is the run's sample's (none is assumed):

    gelrig run examples/load_unload.py --sample-diameter "18.63 mm" --out runs/cycles
    gelrig run examples/load_unload.py --sample-diameter "18.63 mm" \
        --rig examples/rigs/compression_mdr.toml --out runs/mdr
"""

import gelrig

SPEEDS = ("1 um/s", "10 um/s", "100 um/s")


@gelrig.protocol(rig="compression", name="Loading-unloading at three rates")
def load_unload(run: gelrig.Run) -> None:
    """Contact search, then one loading-unloading cycle per speed, rests between."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    for i, speed in enumerate(SPEEDS):
        if i:
            run.step("rest", name=f"rest {i}", duration="60 s", clear="2 mm")
        run.step("load_unload", name=f"cycle at {speed.replace('/', ' per ')}",
                 strain=0.04, speed=speed, approach="0.05 mm",
                 rate="100 Hz")


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
