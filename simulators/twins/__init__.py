"""The simulated rigs: each rig's simulators built from the rig file's typed truth, and coupled.

A rig's *twin* is the rig with every instrument replaced by its simulator, on one clock. These
modules own the rig physics the instruments share: :mod:`.compression` (the stage carries the
plate into the sphere the load cell reads), :mod:`.shear` (the two spheres on the rheometer's
arm). The composition root (``gelrig.factory``) only asks them for the simulators and connects
the real drivers to them. They import ``gelrig.instrument`` and the simulators only.
"""
