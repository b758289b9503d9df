"""A creep test: find first touch, then ramp until the force reaches 100 mN and hold it for
300 s by moving the stage under feedback (``creep``, from compression_steps.py: every second
the mean force is compared with the target and the plate corrected through the Hertz
stiffness). Records the hold's force, position and overlap columns; results: where the plate
started and ended the hold (the creep), ten points of overlap against time, and the force's
rms error from its target. The same test as a protocol file: examples/creep.toml.

    gelrig run examples/creep.py --out runs/creep
"""

import compression_steps  # noqa: F401 (registers rest, load_unload, creep)

import gelrig


@gelrig.protocol(rig="compression", name="Creep at 100 mN")
def creep(run: gelrig.Run) -> None:
    """Contact search, then hold 100 mN for 300 s under feedback."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    run.step("creep", name="creep at 100 mN", force="100 mN", hold="300 s", speed="20 um/s",
             period="1 s", gain=0.5, rate="100 Hz")


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
