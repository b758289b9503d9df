"""A relaxation series compared across strains: find first touch, then ramp and hold at 2, 4
and 6 % strain of the diameter (0.002 /s, 600 s holds at 100 Hz), with the plate backed off
and the force recorded for 120 s between holds (the built-in ``rest`` step). Records one step
per hold (force, position and overlap columns; results: the relaxation fits of each hold) and
one per rest (the force baseline and its drift). At the end the run's log compares the fits
across strains: a linear material (the simulator's) gives the same G_e and tau at every strain,
within their standard errors.

The sphere's diameter is the run's sample's (none is assumed):

    gelrig run examples/relaxation_series.py --sample-diameter "18.63 mm" --out runs/series
    gelrig plan examples/relaxation_series.py --sample-diameter "18.63 mm"
"""

import gelrig

STRAINS = (0.02, 0.04, 0.06)


@gelrig.protocol(rig="compression", name="Relaxation series at 2, 4 and 6 % strain")
def relaxation_series(run: gelrig.Run, strains: tuple[float, ...] = STRAINS,
                      hold: str = "600 s", rest: str = "120 s") -> None:
    """Contact search, then ramp_hold at each strain with a rest between holds, and the fits
    compared across strains (parameters: ``gelrig run relaxation_series.py --param
    strains=[0.03,0.05]``)."""
    run.step("compression_contact_search", name="contact search", speed="0.3 mm/s")
    fits = {}
    for i, strain in enumerate(strains):
        if i:
            run.step("rest", name=f"rest {i}", duration=rest, clear="2 mm")
        held = run.step("ramp_hold", name=f"hold at {strain:.0%}", strain=strain,
                        strain_rate="0.002 /s", hold=hold, rate="100 Hz", terms=1)
        fits[strain] = held.fits[0]
    for strain, fit in fits.items():
        if "error" in fit:
            run.log(f"strain {strain:.0%}: no fit ({fit['error']})")
            continue
        run.log(f"strain {strain:.0%}: G_e = {fit['G_e'] / 1e3:.3f} kPa, tau = "
                f"{fit['relax'][0]['tau']:.0f} +- {fit['stderr']['tau_1']:.0f} s")


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
