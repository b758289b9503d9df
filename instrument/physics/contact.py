"""Normal contact force of two viscoelastic spheres (or a plate and a sphere).

The one physics of gelrig (../shared/physics.md section 1): Hertz with a relaxing modulus
written as a Prony series, the hereditary integral of Jian et al. (2019) evaluated with its
exact O(N) recursion, and the paper's no-adhesion cutoff applied on the output only::

    K      = 4 sqrt(R) / (3 (1 - nu))
    x      = max(delta, 0) ** 1.5
    F_e    = K G_e x
    F_hat  = K sum_i G_i h_i,   h_i(t) = int_0^t exp(-(t - s)/tau_i) dx(s)
    F_perp = max(0, F_e + F_hat)

The prefactor is the paper's (textbook plate-sphere Hertz would be twice it); the paper's
fitted moduli are defined through it, so it is used everywhere (docs/decisions/0002).
Contact starts with no history; a jump of x at the first sample loads instantaneously.
Each contact starts fresh (physics.md section 1): where the overlap returns to <= 0 the
hereditary state is discarded, so the next contact meets no hidden force. Carrying the state
across separations is a named sensitivity option, ``carry_history`` (docs/decisions/0140).
Simulators and the model obtain their contact through :func:`make_contact`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gelrig.instrument.core.arrays import FloatArray
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.scipy_ext import first_order
from gelrig.instrument.physics.material import Material as Material  # re-exported
from gelrig.instrument.physics.material import RelaxationTerm as RelaxationTerm

#: Largest decay exponent (sum of dt/tau) spanned by one block of the variable-step solver.
_MAX_SPAN = 20.0
#: Backwards steps smaller than this (relative to the time) are round-off, taken as zero.
_TIME_JITTER = 1e-12
#: Relative tolerance under which time steps count as uniform (then scipy's lfilter runs).
_UNIFORM_RTOL = 1e-9


def hertz_prefactor(radius: float, nu: float = 0.5) -> float:
    """K = 4 sqrt(R) / (3 (1 - nu)), the paper's prefactor (units m^0.5)."""
    if not radius > 0:
        raise ConfigError("radius", radius, "must be > 0 m")
    if not (0 <= nu < 1):
        raise ConfigError("nu", nu, "Poisson ratio must satisfy 0 <= nu < 1")
    return 4.0 * math.sqrt(radius) / (3.0 * (1.0 - nu))


def effective_radius(r1: float, r2: float = math.inf) -> float:
    """1/R = 1/R1 + 1/R2; a plate is ``r2 = inf`` (then R = R1)."""
    for name, r in (("R1", r1), ("R2", r2)):
        if not r > 0:
            raise ConfigError(name, r, "must be > 0 m (inf for a plate)")
    if math.isinf(r2):
        return r1
    if math.isinf(r1):
        return r2
    return r1 * r2 / (r1 + r2)


def hertz_power(delta: ArrayLike) -> FloatArray:
    """x = max(delta, 0) ** 1.5, computed as x sqrt(x) (several times faster than ``**``)."""
    d = np.maximum(np.asarray(delta, dtype=float), 0.0)
    root = np.sqrt(d)
    return np.multiply(d, root, out=d)


def _step_weight(r: FloatArray) -> FloatArray:
    """(tau/dt)(1 - exp(-dt/tau)) for r = dt/tau; 1 at r = 0 (an instantaneous jump)."""
    safe = np.where(r > 0, r, 1.0)
    return np.where(r > 0, -np.expm1(-safe) / safe, 1.0)


def _uniform_run(
    x: FloatArray, x_prev: float, r: float, h_prev: float, scale: float = 1.0
) -> FloatArray:
    """``scale * h`` over samples sharing one step ``r = dt/tau``, as a linear filter on x.

    ``h[k] = E h[k-1] + w (x[k] - x[k-1])`` is ``lfilter([w, -w], [1, -E], x)`` (run by
    :func:`first_order`) with the state ``zi = E h_prev - w x_prev`` carrying the history in;
    ``scale`` (e.g. K G_i) is folded into the coefficients, which saves a pass over the data.
    """
    e = math.exp(-r)
    w = -math.expm1(-r) / r if r > 0 else 1.0
    sw = scale * w
    return first_order(sw, -sw, -e, x, scale * (e * h_prev - w * x_prev))


def _diff_from(a: FloatArray, before: float) -> FloatArray:
    """``np.diff(a, prepend=before)`` for a 1-D array, without its general-case overhead
    (it is called once per simulator read)."""
    out = np.empty(a.size)
    if a.size:
        out[0] = a[0] - before
        np.subtract(a[1:], a[:-1], out=out[1:])
    return out


def _irregular(r: FloatArray, x: FloatArray, x_prev: float, h_prev: float) -> FloatArray:
    """Recursion for irregular steps: ``h_n = exp(-L_n) (h_s + sum_k u_k exp(L_k))``.

    L is the cumulative decay exponent within a block; blocks keep it below _MAX_SPAN so the
    growing factors stay far from overflow. Exact to rounding, vectorised per block.
    """
    dx = _diff_from(x, x_prev)
    # Every step positive (the usual case): the weight without _step_weight's guards.
    u = (-np.expm1(-r) / r if bool((r > 0).all()) else _step_weight(r)) * dx
    n = x.size
    out = np.empty(n)
    cum = np.cumsum(r)
    start = 0
    while start < n:
        limit = cum[start] + _MAX_SPAN
        # searchsorted(side="right") on the non-decreasing cum: all of it when the last fits.
        end = n if cum[-1] <= limit else int(np.searchsorted(cum, limit, side="right"))
        end = max(end, start + 1)
        lo = cum[start:end] - cum[start]
        first = math.exp(-r[start]) * h_prev + u[start]
        acc = np.empty(end - start)
        acc[0] = 0.0
        np.cumsum(u[start + 1 : end] * np.exp(lo[1:]), out=acc[1:])
        acc += first
        out[start:end] = acc * np.exp(-lo)
        h_prev = float(out[end - 1])
        start = end
    return out


def _runs(r: FloatArray) -> NDArray[np.intp]:
    """Start indices of the runs of equal steps in ``r`` (always begins with 0)."""
    if r.size < 2:
        return np.zeros(1, dtype=np.intp)
    change = np.abs(r[1:] - r[:-1]) > _UNIFORM_RTOL * np.maximum(np.abs(r[1:]), 1e-300)
    return np.concatenate(([0], 1 + np.flatnonzero(change)))


def hereditary(
    dt: FloatArray, x: FloatArray, tau: float, x_prev: float = 0.0, h_prev: float = 0.0
) -> FloatArray:
    """h(t) = int exp(-(t - s)/tau) dx(s) sampled at each step, by the exact O(N) recursion.

    ``dt[n]`` is the step that ends at sample n; ``x_prev`` and ``h_prev`` are the state before
    the first sample (0 and 0 for a fresh contact, so a first sample with x > 0 loads at once).
    Runs of equal steps go through scipy.signal.lfilter; irregular steps through a blocked
    closed form. Both are exact to rounding for x linear within each step.
    """
    if x.size == 0:
        return np.empty(0)
    if math.isinf(tau):
        return h_prev + (x - x_prev)
    r = dt / tau
    starts = _runs(r)
    if starts.size > max(8, x.size // 256):
        return _irregular(r, x, x_prev, h_prev)
    out = np.empty(x.size)
    bounds = [*starts.tolist(), x.size]
    for a, b in itertools.pairwise(bounds):
        out[a:b] = _uniform_run(x[a:b], x_prev, float(r[a]), h_prev)
        x_prev, h_prev = float(x[b - 1]), float(out[b - 1])
    return out


def _contact_runs(inside: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``inside``."""
    edges = np.flatnonzero(inside[1:] != inside[:-1]) + 1
    bounds = [0, *edges.tolist(), inside.size]
    first = bool(inside[0])
    return [(a, b) for k, (a, b) in enumerate(itertools.pairwise(bounds)) if (k % 2 == 0) == first]


def _runs_of_contact(x: FloatArray) -> list[tuple[int, int]]:
    """(start, stop) of each run of x > 0 in ``x >= 0``, from the positions of its zeros (few
    in a record: one pass when in contact throughout)."""
    if x.all():
        return [(0, x.size)]
    zeros = np.flatnonzero(x == 0.0)
    if zeros.size > x.size // 64:
        return _contact_runs(x > 0)
    bounds = np.concatenate(([-1], zeros, [x.size]))
    gap = np.flatnonzero(bounds[1:] - bounds[:-1] > 1)
    return list(zip((bounds[gap] + 1).tolist(), bounds[gap + 1].tolist(), strict=True))


def hereditary_contacts(
    dt: FloatArray, x: FloatArray, tau: float, carry_history: bool = False
) -> FloatArray:
    """:func:`hereditary` over a record that may separate: each run of x > 0 starts with no
    history (the apart sample before it), and h = 0 where x = 0, unless ``carry_history``."""
    if carry_history or x.size == 0 or bool(x.all()):
        return hereditary(dt, x, tau)
    out = np.zeros(x.size)
    if x.any():
        for a, b in _contact_runs(x > 0):
            out[a:b] = hereditary(dt[a:b], x[a:b], tau)
    return out


@dataclass
class NormalContact:
    """Streaming normal-force state of one contact, stepped with its owner's time steps.

    A simulator calls :meth:`step` (one sample) or :meth:`block` (arrays) with increasing
    times; variable steps are allowed. Where the overlap is <= 0 the bodies are apart: the
    hereditary state is discarded there (a fresh contact follows), unless ``carry_history``,
    in which case it persists and only decays (x = 0, dx = 0).
    """

    material: Material
    radius: float
    t_last: float | None = None
    x_last: float = 0.0
    h: FloatArray = field(default_factory=lambda: np.zeros(0))
    carry_history: bool = field(default=False, kw_only=True)

    def __post_init__(self) -> None:
        self.k = hertz_prefactor(self.radius, self.material.nu)
        if self.h.size != len(self.material.relax):
            self.h = np.zeros(len(self.material.relax))
        self._taus = np.array([t.tau for t in self.material.relax], dtype=float)
        self._gs = np.array([t.g for t in self.material.relax], dtype=float)

    def step(self, t: float, delta: float) -> float:
        """Advance to time ``t`` (s) at overlap ``delta`` (m); return F_perp (N)."""
        x = max(delta, 0.0) ** 1.5
        dt = 0.0 if self.t_last is None else t - self.t_last
        if dt < 0:
            if dt < -_TIME_JITTER * max(1.0, abs(t)):
                raise ValueError(f"time went backwards: {t} s after {self.t_last} s")
            dt = 0.0
        if x == 0.0 and not self.carry_history:  # apart: the contact's history ends here
            self.h[:] = 0.0
            self.t_last, self.x_last = t, 0.0
            return 0.0
        dx = x - self.x_last
        hat = 0.0
        for i in range(self.h.size):
            tau = self._taus[i]
            if math.isinf(tau):
                e, w = 1.0, 1.0
            elif dt > 0:
                r = dt / tau
                e = math.exp(-r)
                w = -math.expm1(-r) / r
            else:
                e, w = 1.0, 1.0
            self.h[i] = e * self.h[i] + w * dx
            hat += self._gs[i] * self.h[i]
        self.t_last, self.x_last = t, x
        return max(0.0, self.k * (self.material.g_e * x + hat))

    def block(self, t: ArrayLike, delta: ArrayLike) -> FloatArray:
        """Advance through arrays of times (s) and overlaps (m); return F_perp (N) per sample."""
        elastic, hereditary = self.block_components(t, delta)
        return np.maximum(elastic + hereditary, 0.0)

    def block_components(self, t: ArrayLike, delta: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Like :meth:`block` but return (F_e, F_hat) before the cutoff."""
        t = np.asarray(t, dtype=float)
        x = hertz_power(delta)
        if t.shape != x.shape or t.ndim != 1:
            raise ValueError("t and delta must be 1-D arrays of the same length")
        if t.size == 0:
            return np.empty(0), np.empty(0)
        if not self.carry_history and not x.any():  # apart throughout: no contact, no history
            last = float(t[0]) if self.t_last is None else self.t_last
            tol = _TIME_JITTER * max(1.0, abs(float(t[-1])))
            if float(t[0]) - last < -tol or (
                    t.size > 1 and float(np.min(t[1:] - t[:-1])) < -tol):
                raise ValueError("times must not decrease")
            self.h[:] = 0.0
            self.t_last, self.x_last = float(t[-1]), 0.0
            return x, np.zeros(t.size)
        dt = _diff_from(t, t[0] if self.t_last is None else self.t_last)
        if np.any(dt < 0):
            # Round-off between clocks computed two ways (a few ulps) is not a time reversal.
            if np.any(dt < -_TIME_JITTER * max(1.0, abs(float(t[-1])))):
                raise ValueError("times must not decrease")
            dt = np.maximum(dt, 0.0)
        return self._advance(dt, x, float(t[-1]))

    def block_uniform(self, delta: ArrayLike, dt: float) -> FloatArray:
        """Advance by samples every ``dt`` (s) after the last one; return F_perp (N).

        The fast path for hardware-timed records: no time array, one filter pass per term.
        A fresh contact starts at t = 0 with its first sample.
        """
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        # hertz_power with its square root's buffer reused for the output (one fewer array
        # to allocate and fault in: this is the simulators' per-read path).
        x = np.maximum(np.asarray(delta, dtype=float), 0.0)
        n = x.size
        if n == 0:
            return np.empty(0)
        total = np.sqrt(x)
        np.multiply(x, total, out=x)
        fresh = self.t_last is None
        t_end = (0.0 if fresh else float(self.t_last or 0.0)) + dt * (n - 1 if fresh else n)
        # Each run of overlap > 0 is its own uniform filter pass: the first run continues the
        # state (or loads at once on a fresh contact), later runs start from the apart sample
        # before them with no history, exactly as the per-contact path of :meth:`_advance`.
        runs = [(0, n)] if self.carry_history else _runs_of_contact(x)
        np.multiply(x, self.k * self.material.g_e, out=total)
        for i in range(self.h.size):
            tau, g = float(self._taus[i]), float(self._gs[i])
            scale = self.k * g if g > 0 else 1.0
            for a, b in runs:
                h_prev, x_prev = (float(self.h[i]), self.x_last) if a == 0 else (0.0, 0.0)
                if tau < math.inf and not (fresh and a == 0):  # the common case, inline
                    hi = _uniform_run(x[a:b], x_prev, dt / tau, h_prev, scale)
                else:
                    hi = self._uniform_term(x[a:b], x_prev, h_prev, dt / tau, scale, fresh)
                self.h[i] = hi[-1] / scale
                if g > 0:
                    total[a:b] += hi
            if not self.carry_history and x[-1] == 0.0:
                self.h[i] = 0.0
        self.t_last = t_end
        self.x_last = float(x[-1])
        return np.maximum(total, 0.0, out=total)

    @staticmethod
    def _uniform_term(x: FloatArray, x_prev: float, h_prev: float, r: float, scale: float,
                      load_at_once: bool) -> FloatArray:
        """``scale * h`` of one term over samples every ``r = dt/tau``; ``load_at_once``: the
        first sample is a jump (step 0) from ``x_prev``, as a fresh contact's first sample."""
        if r == 0.0:  # tau = inf: no decay
            return scale * (h_prev + (x - x_prev))
        if not load_at_once:
            return _uniform_run(x, x_prev, r, h_prev, scale)
        if x.size == 1:
            return np.array([scale * (h_prev + x[0] - x_prev)])
        first = h_prev + x[0] - x_prev
        hi = np.empty(x.size)
        hi[0] = scale * first
        hi[1:] = _uniform_run(x[1:], float(x[0]), r, first, scale)
        return hi

    def reset(self) -> None:
        """Discard the hereditary state: the next sample starts a fresh contact."""
        self.h[:] = 0.0
        self.x_last = 0.0

    def snapshot(self) -> tuple[float | None, float, FloatArray]:
        """The state, for :meth:`restore` (a simulator's non-committing look-ahead)."""
        return self.t_last, self.x_last, self.h.copy()

    def restore(self, state: object) -> None:
        """Return to a state taken by :meth:`snapshot`."""
        t_last, x_last, h = cast(tuple[float | None, float, FloatArray], state)
        self.t_last, self.x_last, self.h = t_last, x_last, h.copy()

    def _advance(
        self, dt: FloatArray, x: FloatArray, t_end: float
    ) -> tuple[FloatArray, FloatArray]:
        hat = np.zeros(x.size)
        if self.h.size == 0:
            pass
        elif self.carry_history or bool(x.all()):
            self._hereditary_run(dt, x, hat, self.x_last)
        else:
            # Apart samples (x = 0) end a contact: hat is 0 there and the next contact starts
            # from no history, so only the runs in contact need the recursion.
            runs = _contact_runs(x > 0) if x.any() else []
            for a, b in runs:
                if a > 0:
                    self.h[:] = 0.0
                self._hereditary_run(dt[a:b], x[a:b], hat[a:b], self.x_last if a == 0 else 0.0)
            if x[-1] == 0.0:
                self.h[:] = 0.0
        self.t_last, self.x_last = t_end, float(x[-1])
        hat *= self.k
        return (self.k * self.material.g_e) * x, hat

    def _hereditary_run(self, dt: FloatArray, x: FloatArray, out: FloatArray,
                        x_prev: float) -> None:
        """Add sum_i G_i h_i over one run of samples to ``out``, advancing ``self.h``."""
        for i in range(self.h.size):
            hi = hereditary(dt, x, float(self._taus[i]), x_prev, float(self.h[i]))
            out += self._gs[i] * hi
            self.h[i] = hi[-1]


def normal_force(
    t: ArrayLike, delta: ArrayLike, material: Material, radius: float,
    *, carry_history: bool = False,
) -> FloatArray:
    """Batch F_perp (N) of a fresh contact over whole arrays of time (s) and overlap (m)."""
    return NormalContact(material, radius, carry_history=carry_history).block(t, delta)


def normal_force_uniform(
    delta: ArrayLike, dt: float, material: Material, radius: float,
    *, carry_history: bool = False,
) -> FloatArray:
    """Batch F_perp (N) of a fresh contact sampled every ``dt`` (s) from t = 0."""
    return NormalContact(material, radius, carry_history=carry_history).block_uniform(delta, dt)
