"""Does a compression record tell the truth? The recorded force against the contact model
at the recorded plate position.

A force sample is only as good as the plate position assigned to it: on a twin the contact
is known, so replaying the recorded positions through the same contact model must give the
recorded force within the force noise (issue 24; :mod:`gelrig.clock_check` records the short
protocol on any clock and measures it with this).
"""

from __future__ import annotations

import numpy as np

from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.instrument.physics.truth import CompressionTruth


def model_force(truth: CompressionTruth, t: FloatArray, z: FloatArray) -> FloatArray:
    """The twin's contact model (its material, sphere and first touch) driven through the
    plate positions ``z`` (m) at times ``t`` (s): what the load cell should have read."""
    t = np.asarray(t, dtype=float)
    z = np.asarray(z, dtype=float)
    ok = np.isfinite(z)
    contact = PlateSphereContact(
        truth.material, truth.sphere_diameter / 2, truth.first_touch,
        lambda ts: np.interp(ts, t[ok], z[ok]), vectorized=True, unloading=truth.unloading)
    return contact.force(t)


def residual(truth: CompressionTruth, t: FloatArray, z: FloatArray, f: FloatArray,
             flag: FloatArray | None = None) -> FloatArray:
    """Recorded force less the model force at the recorded positions (N), where the
    position is trusted (finite, and not flagged when ``flag`` is given)."""
    ok = np.isfinite(z) if flag is None else np.isfinite(z) & (np.asarray(flag) == 0)
    return np.asarray(f[ok] - model_force(truth, t, z)[ok], dtype=float)


__all__ = ["model_force", "residual"]
