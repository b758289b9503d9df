"""Reference numbers of the seed paper (physics.md section 4), in SI, in one place.

Demos, tests and the shipped protocols take the paper's values from here.
"""

from __future__ import annotations

from gelrig.instrument.physics.material import Material

# Inter-particle shear rig
ARM = 0.027  # m, rheometer arm
R1_SHEAR = 9.2e-3  # m, upper sphere (on the arm)
R2_SHEAR = 9.96e-3  # m, lower sphere (fixed)
DELTA_MAX_SHOWN = 0.78e-3  # m, the overlap the paper shows
OVERLAP_STEP = 0.1e-3  # m, between the five overlap levels
SPEEDS = (2.38e-5, 4.75e-5, 1.19e-4, 2.37e-4)  # m/s, linear at the arm
MU = 5e-3
SHEAR_FH = Material.of(0.4e4, [(5 * 0.4e4, 2000.0)])  # fit to the horizontal force
SHEAR_FV = Material.of(0.4e4, [(4 * 0.4e4, 2000.0)])  # fit to the vertical force
CONTACT_TORQUE = 0.2e-3  # N m, contact-search threshold at 0.5 rpm
CONTACT_SEARCH_RPM = 0.5

# Plate compression rig
DIAMETER_COMPRESSION = 18.63e-3  # m
R_COMPRESSION = DIAMETER_COMPRESSION / 2
STRAIN_HOLD = 0.06  # 6 % of the diameter
STRAIN_RATE = 0.002  # 1/s, relative to the diameter
HOLD = 3000.0  # s
DEPTH_HOLD = STRAIN_HOLD * DIAMETER_COMPRESSION  # m (1.12 mm)
RAMP_SPEED = STRAIN_RATE * DIAMETER_COMPRESSION  # m/s
PLATES = Material.of(7146.0, [(630.0, 1413.0)])  # 1-term fit, between plates
SHELL = Material.of(13915.0, [(2540.0, 1898.0), (504.0, 172.0)])  # 2-term fit, in the shell
