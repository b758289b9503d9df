"""The paper's inter-particle shear protocol as a script: the same steps and parameters as
``protocols/paper/shear.toml`` (find contact with 1 mm coarse and 0.1 mm fine gap steps at
0.5 rpm until 0.2 mN m, then at 5 overlaps 0.1 mm apart from 0.38 mm and the paper's 4
sliding speeds, sweep 16 mm clockwise, wait 60 s, sweep back, wait 60 s).

Records two steps: ``contact search`` (touch gap, lower-sphere angle) and ``sliding-speed
ladder`` (the arm's stream every 0.1 s: angle, arc travel, torque, normal force, gap, each
sample labelled with its pass, direction, speed and overlap; one result row per pass).

    gelrig run examples/paper_shear.py                  # the built-in simulated rig
    gelrig plan examples/paper_shear.py                 # rehearse it on the rig's twin
"""

import gelrig

#: the paper's four sliding speeds, slowest first (as the protocol file lists them)
SPEEDS = ["2.38e-5 m/s", "4.75e-5 m/s", "1.19e-4 m/s", "2.37e-4 m/s"]


@gelrig.protocol(rig="shear", name="Paper: inter-particle shear, sliding-speed ladder")
def paper_shear(run: gelrig.Run) -> None:
    """Find contact, then sweep C and AC at 5 overlaps and 4 sliding speeds."""
    run.step("shear_contact_search", name="contact search", safe_gap="4 mm", coarse="1 mm",
             fine="0.1 mm", rpm=0.5, threshold="0.2 mN*m", sweep="70 mm")
    run.step("speed_ladder", name="sliding-speed ladder", overlaps=5, first_overlap="0.38 mm",
             overlap_step="0.1 mm", speeds=SPEEDS, travel="16 mm", wait="60 s",
             interval="0.1 s")


if __name__ == "__main__":
    raise SystemExit(gelrig.script_main())
