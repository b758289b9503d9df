"""Plate-on-sphere contact of the compression rig, evaluated lazily for blocks of sample times.

A rigid plate carried by the stage presses on one sphere (physics.md section 3; R = R_sphere).
The coupling to the stage is one function, the plate position (m) at time t (s); the stage
simulator exposes exactly that. Sign convention (docs/decisions/0013)::

    overlap = direction * (plate_position(t) - first_touch)

with ``direction = +1`` when an increasing stage position moves the plate into the sphere
(the default) and ``-1`` for a stage mounted the other way. ``first_touch`` is the stage
position at which the plate meets the sphere's top: the value a contact search must find.

One contact (:func:`~gelrig.instrument.physics.contact_models.make_contact`) carries the hereditary
history for the
whole life of the object (each contact fresh: a retracted plate leaves none), so queries must
come in increasing time; gaps between queries are filled with internal steps so the history
still follows the plate.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import FloatArray, Material
from gelrig.instrument.physics.contact_models import make_contact

#: Plate position (m) as a function of time (s).
PlatePosition = Callable[[float], float]
#: The same, vectorised: an array of times (s) -> an array of positions (m).
PlatePositions = Callable[[FloatArray], FloatArray]


class PlateSphereContact:
    """Force (N) on the load cell from a plate driven into a sphere, as a function of time.

    ``plate_position`` is called per sample time unless ``vectorized`` is True, in which case
    it is called once per block with an array of times (much faster at 1 kHz).
    ``max_gap`` (s) is the longest step the history is advanced by between queried samples.
    ``unloading`` picks the contact model: ``"cutoff"`` (the paper's) or ``"mdr"``
    (physics.md 1b; :func:`~gelrig.instrument.physics.contact_models.make_contact`).
    """

    def __init__(
        self,
        material: Material,
        sphere_radius: float,
        first_touch: float,
        plate_position: PlatePosition | PlatePositions,
        *,
        direction: int = 1,
        vectorized: bool = False,
        max_gap: float = 1.0,
        unloading: str = "cutoff",
    ):
        if not (math.isfinite(sphere_radius) and sphere_radius > 0):
            raise ConfigError("sphere_radius", sphere_radius, "must be a finite length > 0 m")
        if not math.isfinite(first_touch):
            raise ConfigError("first_touch", first_touch, "must be a finite stage position in m")
        if direction not in (1, -1):
            raise ConfigError("direction", direction, "allowed: +1 (position up = into the "
                              "sphere) or -1")
        if not (math.isfinite(max_gap) and max_gap > 0):
            raise ConfigError("max_gap", max_gap, "must be > 0 s")
        self.material = material
        self.sphere_radius = float(sphere_radius)
        self.first_touch = float(first_touch)
        self.direction = direction
        self.max_gap = float(max_gap)
        self._position = plate_position
        self._vectorized = vectorized
        self._contact = make_contact(material, self.sphere_radius, unloading)

    @property
    def t_last(self) -> float | None:
        """Time (s) of the last evaluated step, None before the first query."""
        return self._contact.t_last

    def positions(self, t: ArrayLike) -> FloatArray:
        """Plate positions (m) at times ``t`` (s); a pure query, no state changes."""
        times = np.asarray(t, dtype=float)
        if self._vectorized:
            out = np.asarray(self._position(times), dtype=float)  # type: ignore[arg-type]
            if out.shape != times.shape:
                raise ValueError(
                    f"vectorised plate_position returned shape {out.shape} for {times.shape}"
                )
            return out
        fn = self._position
        return np.fromiter((fn(x) for x in times.tolist()), dtype=float, count=times.size)

    def overlap(self, t: ArrayLike) -> FloatArray:
        """Overlap (m) at times ``t`` (s), positive = interpenetration; pure."""
        return self.direction * (self.positions(t) - self.first_touch)

    def force(self, t: ArrayLike) -> FloatArray:
        """Force (N) at increasing times ``t`` (s), advancing the contact history."""
        times = np.asarray(t, dtype=float)
        if times.ndim != 1:
            raise ValueError("t must be a 1-D array of times")
        if times.size == 0:
            return np.empty(0)
        self._fill_gap(float(times[0]))
        return self._contact.block(times, self.overlap(times))

    def force_on_grid(self, t_first: float, dt: float, n: int) -> FloatArray:
        """Force (N) at ``t_first + k dt`` for k < n: a hardware-timed block of samples.

        Takes the uniform fast path when the block continues the previous one on its grid.
        """
        if not dt > 0:
            raise ValueError(f"sample interval must be > 0 s, got {dt}")
        if n <= 0:
            return np.empty(0)
        t = t_first + dt * np.arange(n, dtype=float)
        last = self._contact.t_last
        if last is not None and abs(t_first - dt - last) <= 1e-6 * dt:
            return self._contact.block_uniform(self.overlap(t), dt)
        return self.force(t)

    def _fill_gap(self, t_next: float) -> None:
        """Advance the history in steps of at most ``max_gap`` up to (not including) t_next."""
        last = self._contact.t_last
        if last is None or t_next - last <= self.max_gap:
            return
        steps = math.ceil((t_next - last) / self.max_gap)
        inner = last + (t_next - last) * np.arange(1, steps, dtype=float) / steps
        if inner.size:
            self._contact.block(inner, self.overlap(inner))
