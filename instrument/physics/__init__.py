"""The one contact physics (physics.md): Hertz with a relaxing Prony modulus, the
no-adhesion cutoff and MDR unloading, sliding geometry with Coulomb friction, the paper's numbers.
"""
