"""Analysis of recorded or modelled data: holds and their relaxation fits (offline and live),
per-pass shear quantities and the ladder-wide model fit. Arrays in, dataclasses out.
"""
