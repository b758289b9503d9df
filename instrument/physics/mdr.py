"""Recovery-consistent normal contact: the method of dimensionality reduction (physics.md 1b).

The sphere's axisymmetric contact maps (Popov and Hess) onto a row of independent 1-D
elements at positions x with the profile ``g(x) = x^2 / R``. Each element is a generalised
Maxwell body with stiffness per unit length ``k(t) = G(t) / (1 - nu)``: a spring
``k_e = G_e/(1-nu)`` in parallel with arms (spring ``k_i``, dashpot ``k_i tau_i``). With
displacement ``w`` and arm stretches ``e_i = w - u_i`` (``u_i`` the dashpot coordinates) the
force density is ``q = k_e w + sum_i k_i e_i``.

- In contact ``w = delta - g(x)`` and ``e_i`` follows the exact exponential recursion of
  physics.md 1 (w linear within a step).
- An element leaves contact in the step where ``q`` would turn negative (at the fraction of the
  step where the linearly interpolated q crosses zero); out of contact ``q = 0`` and the
  ``u_i`` relax on their own (the surface recovers on its retardation times).
- It re-enters contact at the first sample where ``delta - g(x) >= w``.

``F_perp = integral of q over the elements in contact``; no cutoff is needed (q >= 0 by
construction). While the contact only grows this equals the hereditary model of
:mod:`gelrig.instrument.physics.contact` (Lee-Radok); on a receding contact it reproduces Ting
(1966).

Numerics: the batch path is event driven. While an element stays in contact its force
density is ``Q(t) - k_e g + sum_i k_i C_i P_i(t)`` with ``Q`` one global linear filter of
delta (shared by all elements) and ``P_i(t) = exp(-t/tau_i)``; while it is free its
displacement is a sum of decaying modes. Only the switching times are searched per element
(window bounds first, exact values only inside flagged windows), so a record costs
O(samples * terms + elements * windows) instead of O(samples * elements). :meth:`step` is the
plain per-sample update, vectorised over the touched elements; it serves as the reference
(the batch equals it to rounding) and runs blocks of up to 16 samples, where setting up the
events would cost more.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import FloatArray, Material, _diff_from, hereditary

#: Default number of elements over the largest expected contact radius.
ELEMENTS = 300
#: Default largest expected overlap (m) when none is given; the grid grows past it if needed.
DELTA_MAX = 2e-3
#: Largest decay exponent (time span / shortest tau) of one sub-block of the batch path.
_SPAN = 8.0
#: Most (element, sample, term) values evaluated at once while refining a switching time.
_CHUNK = 2_000_000
#: Blocks up to this many samples go through the per-sample update instead of the events.
_SMALL = 16
#: Backwards steps smaller than this (relative to the time) are round-off, taken as zero.
_TIME_JITTER = 1e-12

BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.intp]


def _weight(r: FloatArray) -> FloatArray:
    """(tau/dt)(1 - exp(-dt/tau)) for r = dt/tau; 1 at r = 0 (an instantaneous jump)."""
    safe = np.where(r > 0, r, 1.0)
    return np.where(r > 0, -np.expm1(-safe) / safe, 1.0)


def _fraction(num: FloatArray, den: FloatArray) -> FloatArray:
    """Where in a step a linearly interpolated quantity crosses zero, in [0, 1]; 1 where
    round-off leaves no crossing (den <= 0)."""
    out = np.ones_like(num)
    np.divide(num, den, out=out, where=den > 0)
    return np.asarray(np.clip(out, 0.0, 1.0), dtype=float)


@dataclass(frozen=True)
class MdrBlock:
    """One batch of samples: F_perp (N) and the contact radius a (m) at each sample."""

    force: FloatArray
    radius: FloatArray


@dataclass(frozen=True)
class MdrState:
    """Saved state of an :class:`MdrContact` (see :meth:`MdrContact.snapshot`)."""

    t_last: float | None
    delta_last: float
    reach: int
    contact: BoolArray
    w: FloatArray
    e: FloatArray


class MdrContact:
    """Streaming MDR contact with the API of
    :class:`gelrig.instrument.physics.contact.NormalContact`.

    ``MdrContact(material, radius)`` builds ``elements`` elements over the contact radius
    ``sqrt(R delta_max)`` (x >= 0; the row is symmetric). Overlaps beyond ``delta_max`` add
    elements at the same spacing. ``nu`` overrides ``material.nu`` when given.
    """

    def __init__(
        self,
        material: Material,
        radius: float,
        nu: float | None = None,
        elements: int = ELEMENTS,
        delta_max: float = DELTA_MAX,
        *,
        carry_history: bool = True,
    ) -> None:
        if not (math.isfinite(radius) and radius > 0):
            raise ConfigError("radius", radius, "must be > 0 m")
        nu = material.nu if nu is None else nu
        if not 0 <= nu < 1:
            raise ConfigError("nu", nu, "Poisson ratio must satisfy 0 <= nu < 1")
        if not (isinstance(elements, int) and elements >= 4):
            raise ConfigError("elements", elements, "must be an integer >= 4")
        if not (math.isfinite(delta_max) and delta_max > 0):
            raise ConfigError("delta_max", delta_max, "must be > 0 m")
        self.material = material
        self.radius = radius
        self.nu = nu
        self.carry_history = carry_history
        terms = [t for t in material.relax if t.g > 0]
        self._ke = material.g_e / (1.0 - nu)
        self._k = np.array([t.g for t in terms], dtype=float) / (1.0 - nu)
        self._tau = np.array([t.tau for t in terms], dtype=float)
        self._rate = 1.0 / self._tau  # 0 for tau = inf
        self._modes()
        self.dx = math.sqrt(radius * delta_max) / elements
        self._x: FloatArray = np.empty(0)
        self._g: FloatArray = np.empty(0)
        self._contact: BoolArray = np.zeros(0, dtype=bool)
        self._w: FloatArray = np.empty(0)
        self._e: FloatArray = np.empty((self._k.size, 0))
        self._grow(elements)
        self.reset()

    # ----------------------------------------------------------------- set-up and state

    def _modes(self) -> None:
        """Eigen-modes of the free element: du/dt = diag(1/tau) (1 p^T - I) u, w = p . u."""
        m = self._k.size
        k_tot = self._ke + float(self._k.sum())
        self._p = self._k / k_tot
        a = self._rate[:, None] * (np.outer(np.ones(m), self._p) - np.eye(m))
        if m:
            lam, v = np.linalg.eig(a)
            self._lam = np.minimum(lam.real, 0.0)
            self._v = v.real
            self._vinv = np.linalg.inv(self._v)
        else:
            self._lam, self._v, self._vinv = np.empty(0), np.empty((0, 0)), np.empty((0, 0))
        self._pv = self._p @ self._v

    def _grow(self, n: int) -> None:
        """Extend the row to ``n`` elements at spacing dx; new elements start untouched."""
        old = self._x.size
        if n <= old:
            return
        self._x = (np.arange(n, dtype=float) + 0.5) * self.dx
        self._g = np.asarray(self._x**2 / self.radius, dtype=float)
        if old:
            self._contact = np.concatenate((self._contact, np.zeros(n - old, dtype=bool)))
            self._w = np.concatenate((self._w, np.zeros(n - old)))
            self._e = np.concatenate((self._e, np.zeros((self._k.size, n - old))), axis=1)

    def _fit(self, delta_peak: float) -> None:
        """Grow the row so that an overlap ``delta_peak`` cannot reach past its last element."""
        edge = self._x.size * self.dx
        if delta_peak > edge**2 / self.radius:
            self._grow(math.ceil(math.sqrt(self.radius * delta_peak) * 1.05 / self.dx))

    def reset(self) -> None:
        """Discard all state: a fresh contact (untouched, relaxed surface), next sample t = 0."""
        n = self._x.size
        self._contact = np.zeros(n, dtype=bool)
        self._w = np.zeros(n)
        self._e = np.zeros((self._k.size, n))
        self.t_last: float | None = None
        self.delta_last = 0.0
        self._reach = 0  # elements [reach:] have never been touched
        self._cached_dt = math.nan
        self._cached: tuple[FloatArray, FloatArray, FloatArray] = (
            np.empty((0, 1)), np.empty((0, 1)), np.empty((0, 0)))

    def _apart(self, t: float, delta: float) -> None:
        """A sample at overlap <= 0 without carried history: the contact ends here."""
        if self._reach:
            self.reset()
        self.t_last, self.delta_last = t, delta

    def snapshot(self) -> MdrState:
        """A copy of the whole state, for a simulator that peeks ahead and comes back."""
        return MdrState(self.t_last, self.delta_last, self._reach, self._contact.copy(),
                        self._w.copy(), self._e.copy())

    def restore(self, state: object) -> None:
        """Return to a state taken by :meth:`snapshot` (of this contact)."""
        assert isinstance(state, MdrState)
        self.t_last, self.delta_last, self._reach = state.t_last, state.delta_last, state.reach
        self._contact, self._w, self._e = (state.contact.copy(), state.w.copy(),
                                           state.e.copy())
        self._x = (np.arange(self._w.size, dtype=float) + 0.5) * self.dx
        self._g = np.asarray(self._x**2 / self.radius, dtype=float)

    @property
    def elements(self) -> int:
        """Number of elements in the row (grows with the largest overlap seen)."""
        return int(self._x.size)

    @property
    def contact_radius(self) -> float:
        """Contact radius a (m) after the last sample; resolution dx."""
        return self._radius_of(self._contact)

    @property
    def surface(self) -> FloatArray:
        """Displacement w (m) of each element (x >= 0) after the last sample."""
        return self._w.copy()

    @property
    def positions(self) -> FloatArray:
        """Element centres x (m)."""
        return self._x.copy()

    def _radius_of(self, contact: BoolArray) -> float:
        idx = np.flatnonzero(contact)
        return float((idx[-1] + 1) * self.dx) if idx.size else 0.0

    def _density(self, w: FloatArray, e: FloatArray) -> FloatArray:
        return self._ke * w + self._k @ e

    def _free(self, u: FloatArray, s: FloatArray | float) -> FloatArray:
        """Free evolution of dashpot coordinates ``u`` (M, n) over times ``s`` (s)."""
        decay = np.exp(self._lam[:, None] * np.asarray(s, dtype=float))
        return np.asarray(self._v @ (decay * (self._vinv @ u)), dtype=float)

    # ----------------------------------------------------------------- streaming

    def step(self, t: float, delta: float) -> float:
        """Advance to time ``t`` (s) at overlap ``delta`` (m); return F_perp (N)."""
        dt = self._dt(t)
        if delta <= 0 and not self.carry_history:
            self._apart(float(t), float(delta))
            return 0.0
        self._fit(delta)
        force = self._step(dt, float(delta))
        self.t_last, self.delta_last = float(t), float(delta)
        return force

    def _dt(self, t: float) -> float:
        if self.t_last is None:
            return 0.0
        dt = t - self.t_last
        if dt < 0:
            if dt < -_TIME_JITTER * max(1.0, abs(t)):
                raise ValueError(f"time went backwards: {t} s after {self.t_last} s")
            dt = 0.0
        return dt

    def _step(self, dt: float, delta: float) -> float:
        """The per-sample update of physics.md 1b, vectorised over the elements that have
        been touched or that the overlap reaches (the others stay untouched)."""
        nl = max(self._reach, int(np.searchsorted(self._g, delta, side="right")))
        if nl == 0:
            return 0.0
        big_e, wt, phi = self._step_constants(dt)
        g, w, e, c = self._g[:nl], self._w[:nl], self._e[:, :nl], self._contact[:nl]
        dd = delta - self.delta_last
        w_c = delta - g
        e_c = big_e * e + wt * dd
        q_c = self._density(w_c, e_c)
        u_f = phi @ (w - e)
        w_f = self._p @ u_f
        stay = c & (q_c >= 0)
        leave = c & ~stay
        enter = ~c & (w_c >= w_f)
        w_new = np.where(stay | enter, w_c, w_f)
        e_new = np.where(stay, e_c, w_new - u_f)
        if enter.any():
            u0 = w[enter] - e[:, enter]
            gap0 = w[enter] - (self.delta_last - g[enter])
            theta = _fraction(gap0, gap0 - (w_f[enter] - w_c[enter]))
            e_new[:, enter] = self._enter(theta, dt, u0, w_c[enter])
        if leave.any():
            q0 = self._density(w[leave], e[:, leave])
            theta = _fraction(q0, q0 - q_c[leave])
            w_x, u_x = self._leave(theta, dt, dd, self.delta_last - g[leave], e[:, leave])
            w_new[leave] = w_x
            e_new[:, leave] = w_x - u_x
        on = stay | enter
        self._contact[:nl], self._w[:nl], self._e[:, :nl] = on, w_new, e_new
        idx = np.flatnonzero(on)
        if idx.size:
            self._reach = max(self._reach, int(idx[-1]) + 1)
        return 2.0 * self.dx * float(self._density(w_new[on], e_new[:, on]).sum())

    def _step_constants(self, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """E_i, the weights (tau_i/dt)(1 - E_i) as columns, and the free propagator over dt."""
        if dt != self._cached_dt:
            r = dt * self._rate
            phi = (self._v * np.exp(self._lam * dt)[None, :]) @ self._vinv
            self._cached = (np.exp(-r)[:, None], _weight(r)[:, None], phi)
            self._cached_dt = dt
        return self._cached

    def _enter(
        self, theta: FloatArray, dt: float | FloatArray, u0: FloatArray, w1: FloatArray
    ) -> FloatArray:
        """Arm stretches at the end of a step in which free elements touch at ``theta``.

        Free from dashpot coordinates ``u0`` up to ``theta dt``, then in contact with w linear
        up to ``w1`` at the end of the step (so a fresh element loads its arms only by what
        the indenter pushed after the touch).
        """
        u1 = self._free(u0, theta * dt)
        w_touch = self._p @ u1
        r2 = self._rate[:, None] * ((1.0 - theta) * dt)
        return np.asarray(np.exp(-r2) * (w_touch - u1) + _weight(r2) * (w1 - w_touch),
                          dtype=float)

    def _leave(
        self, theta: FloatArray, dt: float | FloatArray, dd: float | FloatArray,
        w0: FloatArray, e0: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """State at the end of a step in which elements separate at fraction ``theta``.

        In contact (w linear) up to ``theta dt`` from (w0, e0), free for the rest.
        """
        s1 = theta * dt
        r1 = self._rate[:, None] * s1
        e1 = np.exp(-r1) * e0 + _weight(r1) * (theta * dd)
        u1 = (w0 + theta * dd) - e1
        u2 = self._free(u1, (1.0 - theta) * dt)
        return self._p @ u2, u2

    # ----------------------------------------------------------------- batch

    def block(self, t: ArrayLike, delta: ArrayLike) -> FloatArray:
        """Advance through arrays of times (s) and overlaps (m); return F_perp (N) per sample."""
        return self.block_detail(t, delta).force

    def block_uniform(self, delta: ArrayLike, dt: float) -> FloatArray:
        """Advance by samples every ``dt`` (s) after the last one; return F_perp (N).

        A fresh contact starts at t = 0 with its first sample.
        """
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        d = np.asarray(delta, dtype=float)
        if self.t_last is None:
            t = np.arange(d.size) * dt
        else:
            t = self.t_last + dt * np.arange(1, d.size + 1)
        return self.block(t, d)

    def block_detail(self, t: ArrayLike, delta: ArrayLike) -> MdrBlock:
        """Like :meth:`block`, also returning the contact radius a (m) at each sample."""
        t = np.asarray(t, dtype=float)
        d = np.asarray(delta, dtype=float)
        if t.shape != d.shape or t.ndim != 1:
            raise ValueError("t and delta must be 1-D arrays of the same length")
        if t.size == 0:
            return MdrBlock(np.empty(0), np.empty(0))
        apart = d <= 0
        if self.carry_history or not apart.any():
            return self._contact_block(t, d)
        # fresh contacts: each run of samples in contact starts from a discarded state
        self._dt(float(t[0]))  # times must not go backwards across the split either
        force, radius = np.zeros(t.size), np.zeros(t.size)
        edges = np.flatnonzero(np.diff(apart.astype(np.int8)))  # last sample of each run
        starts = np.concatenate(([0], edges + 1))
        ends = np.concatenate((edges + 1, [t.size]))
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            if apart[a]:
                self._apart(float(t[b - 1]), float(d[b - 1]))
            else:
                part = self._contact_block(t[a:b], d[a:b])
                force[a:b], radius[a:b] = part.force, part.radius
        return MdrBlock(force, radius)

    def _contact_block(self, t: FloatArray, d: FloatArray) -> MdrBlock:
        """The batch path over samples (any overlap) continuing the current state."""
        dt = _diff_from(t, t[0] if self.t_last is None else self.t_last)
        if np.any(dt < 0):
            if np.any(dt < -_TIME_JITTER * max(1.0, abs(float(t[-1])))):
                raise ValueError("times must not decrease")
            dt = np.maximum(dt, 0.0)
        self._fit(float(d.max()))
        force = np.empty(t.size)
        radius = np.empty(t.size)
        if t.size <= _SMALL:  # the per-sample update is cheaper than setting up the events
            for n in range(t.size):
                force[n] = self._step(float(dt[n]), float(d[n]))
                radius[n] = self.contact_radius
                self.t_last, self.delta_last = float(t[n]), float(d[n])
            return MdrBlock(force, radius)
        finite = self._rate[self._rate > 0]
        rate = float(finite.max()) if finite.size else 0.0
        start = 0
        while start < t.size:
            end = t.size
            if rate > 0:  # keep (t - t_start) / tau_min <= _SPAN within a sub-block
                end = max(start + 1, int(np.searchsorted(t, t[start] + _SPAN / rate, "right")))
            f, a = _Sub(self, t[start:end], d[start:end], dt[start:end]).run()
            force[start:end], radius[start:end] = f, a
            self.t_last, self.delta_last = float(t[end - 1]), float(d[end - 1])
            start = end
        return MdrBlock(force, radius)


class _Sub:
    """One sub-block of the batch path: samples 0..L-1 after the contact's stored state."""

    def __init__(self, owner: MdrContact, t: FloatArray, d: FloatArray, dt: FloatArray):
        self.o = owner
        self.t, self.d, self.dt = t, d, dt
        self.n = t.size
        m = owner._k.size
        self.t_prev = t[0] - dt[0]
        self.h = np.empty((m, self.n))
        for i in range(m):
            self.h[i] = hereditary(dt, d, float(owner._tau[i]), owner.delta_last, 0.0)
        self.pp = np.exp(-np.outer(owner._rate, t - t[0]))  # P_i(n), 1 at the first sample
        self.q = owner._ke * d + owner._k @ self.h
        self.d_peak = float(d.max())
        self.e0 = np.exp(-dt[0] * owner._rate)  # E_i at the first sample
        win = max(32, self.n // 512)
        self.ws = np.arange(0, self.n, win)
        self.we = np.minimum(self.ws + win, self.n)
        self.win = win

    # -- searches -----------------------------------------------------------------

    def _flags(self, lower: FloatArray, start: IntArray, w0: int) -> BoolArray:
        """(element, window) flags: the lower bound (given from window w0 on) is <= 0 in a
        window not before the element's start."""
        flag = np.zeros((start.size, self.ws.size), dtype=bool)
        flag[:, w0:] = (lower <= 0) & (self.we[None, w0:] - 1 >= start[:, None])
        return flag

    def _refine(
        self, flag: BoolArray, start: IntArray,
        value: Callable[[IntArray, IntArray], FloatArray],
    ) -> IntArray:
        """First sample >= start in the flagged windows where ``value(jj, idx) < 0``; n if none.

        Each element's first flagged window is tried first (where a switch usually is); the
        rest go in rounds of each unresolved element's next 3, 12, 48 ... flagged windows.
        """
        k = flag.shape[0]
        first = np.full(k, self.n, dtype=np.intp)
        rows = np.flatnonzero(flag.any(axis=1))
        if not rows.size:
            return first
        head = np.argmax(flag[rows], axis=1)
        self._try(rows, head, start, value, first)
        left = rows[first[rows] == self.n]
        if not left.size:
            return first
        sub = flag[left]
        sub[np.arange(left.size), head[first[rows] == self.n]] = False
        jl, w = np.nonzero(sub)  # row-major: by element, then window (time) order
        if not jl.size:
            return first
        j = left[jl]
        heads = np.flatnonzero(np.r_[True, jl[1:] != jl[:-1]])
        rank = np.arange(j.size) - np.repeat(heads, np.diff(np.r_[heads, j.size]))
        lo, hi = 0, 3
        top = int(rank.max())
        while lo <= top:
            pick = np.flatnonzero((rank >= lo) & (rank < hi))
            pick = pick[first[j[pick]] == self.n]
            if pick.size:
                self._try(j[pick], w[pick], start, value, first)
            lo, hi = hi, 4 * hi
        return first

    def _try(
        self, j: IntArray, w: IntArray, start: IntArray,
        value: Callable[[IntArray, IntArray], FloatArray], first: IntArray,
    ) -> None:
        """Evaluate ``value`` in windows ``w`` of elements ``j``; lower ``first`` where < 0."""
        per = max(1, _CHUNK // (self.win * max(1, self.o._k.size)))
        lanes = np.arange(self.win)
        for s in range(0, j.size, per):
            jj, ww = j[s : s + per], w[s : s + per]
            idx = self.ws[ww][:, None] + lanes[None, :]
            valid = (idx < self.we[ww][:, None]) & (idx >= start[jj][:, None])
            idx = np.minimum(idx, self.n - 1)
            neg = valid & (value(jj, idx) < 0)
            hit = neg.any(axis=1)
            if hit.any():
                np.minimum.at(first, jj[hit], idx[hit, np.argmax(neg[hit], axis=1)])

    def first_exit(self, g: FloatArray, c: FloatArray, start: IntArray) -> IntArray:
        """First sample >= start where an element in contact would have q < 0."""
        o = self.o
        w0 = int(start.min()) // self.win
        ws, we = self.ws[w0:], self.we[w0:]
        q_min = np.minimum.reduceat(self.q, ws)
        kc = o._k[:, None] * c  # (M, k)
        ends = np.minimum(kc[:, :, None] * self.pp[:, None, ws],
                          kc[:, :, None] * self.pp[:, None, we - 1]).sum(axis=0)
        lower = q_min[None, :] - o._ke * g[:, None] + ends
        flag = self._flags(lower, start, w0)

        def value(jj: IntArray, idx: IntArray) -> FloatArray:
            out = self.q[idx] - o._ke * g[jj][:, None]
            for i in range(o._k.size):
                out += kc[i, jj][:, None] * self.pp[i, idx]
            return out

        return self._refine(flag, start, value)

    def first_entry(
        self, g: FloatArray, beta: FloatArray, tref: FloatArray, start: IntArray
    ) -> IntArray:
        """First sample >= start where a free element meets the indenter: delta - g >= w."""
        o = self.o
        w0 = int(start.min()) // self.win
        ws, we = self.ws[w0:], self.we[w0:]
        d_max = np.maximum.reduceat(self.d, ws)
        lower = np.zeros((g.size, ws.size))
        dented = np.flatnonzero(np.any(beta != 0, axis=0))  # untouched elements: w = 0
        if dented.size:
            s0 = np.maximum(self.t[ws][None, :] - tref[dented, None], 0.0)
            s1 = np.maximum(self.t[we - 1][None, :] - tref[dented, None], 0.0)
            for m in range(o._lam.size):
                b = beta[m, dented][:, None]
                lower[dented] += np.minimum(b * np.exp(o._lam[m] * s0),
                                            b * np.exp(o._lam[m] * s1))
        flag = self._flags(lower - (d_max[None, :] - g[:, None]), start, w0)

        def value(jj: IntArray, idx: IntArray) -> FloatArray:
            wf = np.zeros(idx.shape)
            s = np.maximum(self.t[idx] - tref[jj][:, None], 0.0)
            for m in range(o._lam.size):
                wf += beta[m, jj][:, None] * np.exp(o._lam[m] * s)
            # the element touches where wf - (delta - g) <= 0: mark those samples negative
            gap = wf - (self.d[idx] - g[jj][:, None])
            return np.where(gap <= 0, -1.0, 1.0)

        return self._refine(flag, start, value)

    # -- the phase loop -------------------------------------------------------------

    def run(self) -> tuple[FloatArray, FloatArray]:
        o = self.o
        n, m = self.n, o._k.size
        contact, w_state, e_state = o._contact, o._w, o._e
        # contact phases: element, first sample counted, coefficients C (M, k), search start
        on = np.flatnonzero(contact)
        c_j, c_a, c_c = on, np.zeros(on.size, dtype=np.intp), e_state[:, on] * self.e0[:, None]
        carried = np.ones(on.size, dtype=bool)
        off = np.flatnonzero(~contact)
        u_off = w_state[off] - e_state[:, off]
        f_j, f_start, f_z = off, np.zeros(off.size, dtype=np.intp), o._vinv @ u_off
        f_tref = np.full(off.size, self.t_prev)
        spans: list[tuple[IntArray, IntArray, IntArray, FloatArray]] = []
        final_w, final_e = w_state.copy(), e_state.copy()
        final_c = contact.copy()
        while c_j.size or f_j.size:
            if c_j.size:
                start = np.where(carried, 0, c_a + 1)
                x = self.first_exit(o._g[c_j], c_c, start)
                spans.append((c_j, c_a, x, c_c))
                stays = x >= n
                js = c_j[stays]
                final_c[js] = True
                final_w[js] = self.d[-1] - o._g[js]
                final_e[:, js] = self.h[:, -1:] + c_c[:, stays] * self.pp[:, -1:]
                go = ~stays
                new_j, new_x = c_j[go], x[go]
                u_x = self._exit_state(new_j, new_x, c_c[:, go], e_state)
                f_j = np.concatenate((f_j, new_j))
                f_start = np.concatenate((f_start, new_x + 1))
                f_z = np.concatenate((f_z, o._vinv @ u_x), axis=1)
                f_tref = np.concatenate((f_tref, self.t[new_x]))
                c_j = np.empty(0, dtype=np.intp)
            if f_j.size:
                g = o._g[f_j]
                beta = o._pv[:, None] * f_z
                a = np.full(f_j.size, n, dtype=np.intp)
                # free w >= sum of the negative modal weights (w >= 0 in continuous time,
                # a little below 0 possible after a step much longer than a tau)
                live = (f_start < n) & (g <= self.d_peak - np.minimum(beta, 0.0).sum(axis=0))
                if live.any():
                    a[live] = self.first_entry(g[live], beta[:, live], f_tref[live],
                                               f_start[live])
                stays = a >= n
                js = f_j[stays]
                u_end = o._v @ (np.exp(o._lam[:, None] * (self.t[-1] - f_tref[stays]))
                                * f_z[:, stays])
                final_c[js] = False
                final_w[js] = o._p @ u_end
                final_e[:, js] = final_w[js] - u_end
                go = ~stays
                ja, aa = f_j[go], a[go]
                e_a = self._entry_state(ja, aa, f_z[:, go], f_tref[go])
                c_j, c_a = ja, aa
                c_c = (e_a - self.h[:, aa]) / self.pp[:, aa] if m else np.zeros((0, ja.size))
                carried = np.zeros(ja.size, dtype=bool)
                f_j = np.empty(0, dtype=np.intp)
                f_start = np.empty(0, dtype=np.intp)
                f_z = np.empty((m, 0))
                f_tref = np.empty(0)
        o._contact, o._w, o._e = final_c, final_w, final_e
        touched = [int(j.max()) + 1 for j, a, x, _ in spans if np.any(x > a)]
        o._reach = max([o._reach, *touched])
        return self._sums(spans)

    def _entry_state(self, j: IntArray, a: IntArray, z: FloatArray, tref: FloatArray
                     ) -> FloatArray:
        """Arm stretches e (M, k) at the entry samples a (the step in which they touch)."""
        o = self.o
        first = a == 0
        prev = np.maximum(a - 1, 0)
        t_prev = np.where(first, self.t_prev, self.t[prev])
        d_prev = np.where(first, o.delta_last, self.d[prev])
        u0 = o._v @ (np.exp(o._lam[:, None] * (t_prev - tref)) * z)
        w_now = self.d[a] - o._g[j]
        w_f = o._p @ (o._v @ (np.exp(o._lam[:, None] * (self.t[a] - tref)) * z))
        gap0 = o._p @ u0 - (d_prev - o._g[j])
        theta = _fraction(gap0, gap0 - (w_f - w_now))
        return o._enter(theta, self.dt[a], u0, w_now)

    def _exit_state(
        self, j: IntArray, x: IntArray, c: FloatArray, e_state: FloatArray
    ) -> FloatArray:
        """Dashpot coordinates u (M, k) at the exit samples x (the step in which q < 0)."""
        o = self.o
        prev = np.maximum(x - 1, 0)
        first = x == 0
        e_prev = np.where(first[None, :], e_state[:, j],
                          self.h[:, prev] + c * self.pp[:, prev])
        d_prev = np.where(first, o.delta_last, self.d[prev])
        w_prev = d_prev - o._g[j]
        q_prev = o._density(w_prev, e_prev)
        e_now = self.h[:, x] + c * self.pp[:, x]
        q_now = o._density(self.d[x] - o._g[j], e_now)
        theta = _fraction(q_prev, q_prev - q_now)
        dt = self.dt[x]
        dd = self.d[x] - d_prev
        _, u = o._leave(theta, dt, dd, w_prev, e_prev)
        return u

    def _outer(self, j: IntArray, a: IntArray, x: IntArray) -> FloatArray:
        """(outermost element in contact + 1) per sample: the active set only changes at
        interval ends, so the maximum is taken per segment between them, then repeated."""
        cuts = np.unique(np.concatenate(([0, self.n], a, x)))
        seg = cuts[:-1]
        best = np.zeros(seg.size)
        rows = max(1, _CHUNK // max(1, j.size))
        for s in range(0, seg.size, rows):
            at = seg[s : s + rows, None]
            cover = (a[None, :] <= at) & (x[None, :] > at)
            best[s : s + rows] = np.where(cover, j[None, :] + 1.0, 0.0).max(axis=1, initial=0.0)
        return np.repeat(best, np.diff(cuts))

    def _sums(
        self, spans: list[tuple[IntArray, IntArray, IntArray, FloatArray]]
    ) -> tuple[FloatArray, FloatArray]:
        """F_perp and contact radius per sample from the contact intervals of all elements."""
        o = self.o
        n, m = self.n, o._k.size
        cnt = np.zeros(n + 1)
        gs = np.zeros(n + 1)
        cs = np.zeros((m, n + 1))
        rows: list[tuple[IntArray, IntArray, IntArray]] = []
        for j, a, x, c in spans:
            keep = x > a
            j, a, x, c = j[keep], a[keep], x[keep], c[:, keep]
            np.add.at(cnt, a, 1.0)
            np.add.at(cnt, x, -1.0)
            np.add.at(gs, a, o._g[j])
            np.add.at(gs, x, -o._g[j])
            for i in range(m):
                np.add.at(cs[i], a, c[i])
                np.add.at(cs[i], x, -c[i])
            rows.append((j, a, x))
        cnt = np.cumsum(cnt[:n])
        gs = np.cumsum(gs[:n])
        cs = np.cumsum(cs[:, :n], axis=1)
        total = cnt * self.q - o._ke * gs + (o._k[:, None] * cs * self.pp).sum(axis=0)
        total[cnt < 0.5] = 0.0  # no element in contact: exactly zero, not round-off
        force = np.maximum(2.0 * o.dx * total, 0.0)  # clears round-off below zero only
        radius = np.zeros(n)
        if rows:
            j = np.concatenate([r[0] for r in rows])
            a = np.concatenate([r[1] for r in rows])
            x = np.concatenate([r[2] for r in rows])
            radius = self._outer(j, a, x) * o.dx
        return force, radius


def mdr_contact(material: Material, radius: float, **kw: float | int | None) -> MdrContact:
    """Factory with the shape of ``NormalContact(material, radius)`` (for make_contact)."""
    return MdrContact(material, radius, **kw)  # type: ignore[arg-type]


def mdr_force(t: ArrayLike, delta: ArrayLike, material: Material, radius: float,
              **kw: float | int | None) -> FloatArray:
    """Batch F_perp (N) of a fresh MDR contact over arrays of time (s) and overlap (m)."""
    return mdr_contact(material, radius, **kw).block(t, delta)
