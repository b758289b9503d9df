"""A creep test: find first touch, then ramp until the force reaches 100 mN and hold it for
300 s within 2 mN by moving the stage under feedback (the built-in ``creep`` step: every
second the mean force is compared with the target and the plate corrected through the Hertz
stiffness), then back off and record the sphere recovering at rest. Records the hold's force,
position and overlap columns; results: where the plate started and ended the hold (the creep),
ten points of overlap against time, the force's rms error from its target and whether every
second's mean stayed within the tolerance. The same test as a protocol file:
examples/creep.toml.

    gelrig run examples/creep.py --out runs/creep
"""

import gelrig


@gelrig.protocol(rig="compression", name="Creep at 100 mN")
def creep(run: gelrig.Run) -> None:
    """Contact search, then hold 100 mN for 300 s under feedback, then rest."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    held = run.step("creep", name="creep at 100 mN", force="100 mN", hold="300 s",
                    tolerance="2 mN", speed="20 um/s", period="1 s", gain=0.5, rate="100 Hz")
    run.log(f"creep {held.creep_m * 1e6:.2f} um in {held.held_s:.0f} s; force rms error "
            f"{held.force_rms_error_N * 1e3:.3f} mN, "
            f"{'within' if held.within_tolerance else 'NOT within'} "
            f"{held.tolerance_N * 1e3:g} mN")
    run.step("rest", name="recovery", duration="60 s", clear="2 mm")


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
