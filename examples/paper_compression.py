"""The paper's plate-compression protocol as a script: the same steps and parameters as
``protocols/paper/compression.toml`` (find first touch with 0.5 mm probes at 0.3 mm/s,
ramp to 6 % of the diameter at 0.002 /s, hold 3000 s at 1 kHz, retract, fit).

    gelrig run examples/paper_compression.py            # the built-in simulated rig
    gelrig plan examples/paper_compression.py           # rehearse it on the rig's twin
"""

import gelrig


@gelrig.protocol(rig="compression", name="Paper: plate compression, 6 % ramp and 3000 s hold")
def paper_compression(run: gelrig.Run) -> None:
    """Find first touch, ramp to 6 % strain at 0.002 /s, hold 3000 s at 1 kHz, fit."""
    run.step("compression_contact_search", name="contact search", start="0 mm",
             probe="0.5 mm", speed="0.3 mm/s", threshold="5 mN", retract="0.5 mm",
             confirm=2, rate="100 Hz")
    run.step("ramp_hold", name="ramp and hold", diameter="18.63 mm", strain=0.06,
             strain_rate="0.002 /s", hold="3000 s", rate="1000 Hz", retract="2 mm", terms=2)


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
