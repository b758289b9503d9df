"""Two hydrogel spheres on the rheometer: the contact, integrated lazily along the motion.

Geometry (physics.md section 2, arc treated as a straight line): the upper centre sits at
``x = wrap(angle - lower_angle) * arm`` along the arc from the lower centre (positive
clockwise) and at vertical centre distance ``h = R1 + R2 - (touch_gap - gap)``. The overlap is
``delta = R1 + R2 - hypot(h, x)``; the normal force comes from one contact made by
:func:`gelrig.instrument.physics.contact_models.make_contact`, stepped through the whole trajectory
in order. Each
pass is a fresh contact: where the overlap returns to <= 0 the history is discarded (unless
``carry_history``, docs/decisions/0140), so nothing is integrated while the spheres are
apart. With ``material_vertical`` a second contact gives the F_perp that F_v is resolved
from (the paper's anisotropy).

Forces are resolved in the frame of the motion (``psi = -s x`` with ``s = sign(omega)``) by
:func:`gelrig.instrument.physics.sliding.resolve_forces`, then the lab-frame torque is
``M = s F_h arm + s offset``: positive for a clockwise pass while the contact resists, and
mirrored for a counter-clockwise pass (docs/decisions/0022). At rest there is no friction
direction, so the mu term is dropped (``s = 0``; the frame of a clockwise pass is used).

Integration runs on a grid fixed by the motion alone: each piece between breakpoints (command
times, ramp ends, lift arrivals, trips) is cut into steps of at most ``substep_travel`` of
travel and ``max_substep`` of time, anchored at the piece start, plus the stream's sample
times. How often a client polls therefore never changes the nodes; a reading between grid
nodes is a non-committing step from the last node. A streaming read integrates LOOKAHEAD
seconds beyond itself and later reads are served from it (docs/decisions/0090);
a command, a single reading or a stream change first returns to the node before it.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import numpy as np

from gelrig.instrument.physics.contact import effective_radius
from gelrig.instrument.physics.contact_models import ContactModel, make_contact
from gelrig.instrument.physics.sliding import resolve_forces
from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.mcr501.motion import FloatArray, Lift, Spin

#: Most grid nodes integrated in one block.
CHUNK = 20_000
#: Trip codes (as in the command table's error codes).
TRIP_OVERLOAD = 31
TRIP_TORQUE = 32
#: Lab time (s) a streaming read integrates ahead of itself (docs/decisions/0090).
LOOKAHEAD = 16.0


@dataclass(frozen=True)
class Trip:
    """The instrument stopped itself: ``code`` at time ``t`` (s), arm ``angle`` (rad), ``gap``."""

    code: int
    t: float
    detail: str
    angle: float
    gap: float


class Sample(NamedTuple):
    """True (noise-free) values at one stream sample time (a named tuple: made by the
    thousand per read, and a batch of them is one ``np.array`` call)."""

    t: float
    angle: float
    torque: float
    normal_force: float
    gap: float


@dataclass(frozen=True)
class Forces:
    """True values at one instant: overlap (m), F_perp, F_h (moving frame), F_v (N), torque."""

    delta: float
    f_perp: float
    f_h: float
    f_v: float
    torque: float


#: Sample from a tuple of its five values: tuple.__new__ at C speed (the named tuple's own
#: constructor is a Python function; 159,000 samples in a paper shear run).
_as_sample = partial(tuple.__new__, Sample)


@dataclass
class _Ahead:
    """Nodes integrated beyond the last read: the state to return to, and the samples held
    back until the clock reaches them (absolute time, sample, stream index)."""

    start: tuple[float, float, tuple[float, float, float], tuple[object, object],
                 tuple[float, float, int] | None]
    until: float
    times: list[float] = field(default_factory=list)
    samples: list[Sample] = field(default_factory=list)
    ks: list[int] = field(default_factory=list)
    released: int = 0


class _Abandon(Exception):
    """A look-ahead block reached a limit: integrate without look-ahead instead."""


def _sorted_unique(values: FloatArray) -> FloatArray:
    """``np.unique`` of a float array without NaN: sort, keep the first of each run."""
    if values.size < 2:
        return values
    values = np.sort(values)
    keep = np.empty(values.size, dtype=bool)
    keep[0] = True
    np.not_equal(values[1:], values[:-1], out=keep[1:])
    return values[keep]


class ShearCell:
    """The arm, the lift and the contact, advanced lazily to a requested time."""

    def __init__(self, config: SimConfig, t0: float):
        self.cfg = config
        self.spin = Spin(t0, config.start_angle, 0.0, 0.0, config.acceleration)
        self.lift = Lift(t0, config.start_gap, config.start_gap, config.lift_speed)
        radius = effective_radius(config.r1, config.r2)
        self.contact: ContactModel = make_contact(config.material, radius, config.unloading,
                                                  carry_history=config.carry_history)
        #: The contact F_v is resolved from, when the material is anisotropic.
        self.contact_v: ContactModel | None = None if config.material_vertical is None else (
            make_contact(config.material_vertical, radius, config.unloading,
                         carry_history=config.carry_history))
        self.t_int = t0
        self._anchor = t0
        self._stream: tuple[float, float, int] | None = None  # (t_start, interval, next k)
        self.samples: list[Sample] = []
        self.trips: list[Trip] = []
        self.overflowed = False
        # Overlap, |F_v| and |torque| at the last node: a limit trips when entered or deepened,
        # so motion that backs out of a violation stays possible.
        self._prev = (-math.inf, 0.0, 0.0)
        # advance(t) has integrated every node up to this time, for the current grid (motion
        # pieces and stream); reset by whatever changes the grid.
        self._covered = -math.inf
        # Look-ahead of streaming reads: the nodes integrated beyond the clock, where their
        # samples are collected instead of ``samples``, samples already handed out (stream
        # index below this is not recorded again after a rewind), and whether a limit came
        # near (then no look-ahead until the grid changes).
        self._ahead: _Ahead | None = None
        self._pending: _Ahead | None = None
        self._drop_k = 0
        self._ahead_off = False

    # -- commands (each is a breakpoint of the motion) --------------------------------------

    def set_speed(self, t: float, omega: float) -> None:
        """New set speed (rad/s, + clockwise) from ``t``."""
        self.commit(t)
        self.spin = self.spin.command(t, omega)
        self._grid_changed()

    def set_gap(self, t: float, gap: float) -> None:
        """New lift target (m) from ``t``."""
        self.commit(t)
        self.lift = self.lift.command(t, gap)
        self._grid_changed()

    def start_stream(self, t: float, interval: float) -> None:
        """Sample at ``t + k interval``, k = 1, 2, ...; earlier samples are discarded."""
        self.advance(t)
        self._stream = (t, interval, 1)
        self._drop_k = 0
        self._grid_changed()
        self.samples.clear()
        self.overflowed = False

    def stop_stream(self, t: float) -> None:
        """Stop sampling at ``t``; unread samples and the overflow flag are cleared."""
        self.advance(t)
        self._stream = None
        self._grid_changed()
        self.samples.clear()
        self.overflowed = False

    def _grid_changed(self) -> None:
        self._covered = -math.inf
        self._ahead_off = False

    @property
    def streaming(self) -> bool:
        return self._stream is not None

    # -- evaluation --------------------------------------------------------------------------

    def geometry(self, phi: FloatArray, gap: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Arc offset x (m) of the upper centre from the lower, and vertical distance h (m)."""
        rel = np.remainder(phi - self.cfg.lower_angle + math.pi, 2.0 * math.pi) - math.pi
        x = rel * self.cfg.arm
        h = self.cfg.s - (self.cfg.touch_gap - gap)
        return x, h

    def overlap(self, t: FloatArray) -> FloatArray:
        phi, _ = self.spin.at(t)
        x, h = self.geometry(phi, self.lift.at(t))
        return self.cfg.s - np.hypot(h, x)

    def _resolve(
        self, f_perp: FloatArray, x: FloatArray, h: FloatArray, omega: FloatArray,
        f_perp_v: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """F_h in the moving frame, F_v (from ``f_perp_v`` if given), and the motor torque."""
        s = np.sign(omega)
        if f_perp_v is None and not f_perp.any():  # apart: no force, only the bearing drag
            zero = np.zeros(f_perp.size)
            return zero, zero, s * self.cfg.torque_offset
        if f_perp_v is not None:
            f_h, _, torque = self._resolve(f_perp, x, h, omega)
            _, f_v, _ = self._resolve(f_perp_v, x, h, omega)
            return f_h, f_v, torque
        frame = np.where(s == 0, 1.0, s)
        moving = s != 0
        n_moving = int(np.count_nonzero(moving))
        if n_moving in (0, s.size):
            # One branch for every node (the usual case): the same elementwise operations
            # without the masking.
            mu = self.cfg.mu if n_moving else 0.0
            f_h, f_v = resolve_forces(f_perp, -frame * x / h, 1.0, mu)
        else:
            f_h = np.empty_like(f_perp)
            f_v = np.empty_like(f_perp)
            for mu, mask in ((self.cfg.mu, moving), (0.0, ~moving)):
                # resolve_forces is scale-free in (psi, h): pass psi/h with h = 1 to allow an
                # h that varies while the lift moves.
                fh, fv = resolve_forces(f_perp[mask], -frame[mask] * x[mask] / h[mask], 1.0, mu)
                f_h[mask] = fh
                f_v[mask] = fv
        torque = frame * f_h * self.cfg.arm + s * self.cfg.torque_offset
        return f_h, f_v, torque

    def forces(self, t: float) -> Forces:
        """True values at ``t`` (>= the integrated time), without committing the state."""
        self.advance(t)
        saved = self._save()
        try:
            tt = np.array([t])
            phi, omega = self.spin.at(tt)
            gap = self.lift.at(tt)
            x, h = self.geometry(phi, gap)
            delta = self.cfg.s - np.hypot(h, x)
            f_perp = np.array([self.contact.step(t, float(delta[0]))])
            f_perp_v = None if self.contact_v is None else np.array(
                [self.contact_v.step(t, float(delta[0]))])
            f_h, f_v, torque = self._resolve(f_perp, x, h, omega, f_perp_v)
        finally:
            self._restore(saved)
        return Forces(float(delta[0]), float(f_perp[0]), float(f_h[0]), float(f_v[0]),
                      float(torque[0]))  # fmt: skip

    # -- lazy integration --------------------------------------------------------------------

    def _save(self) -> tuple[object, object]:
        v = self.contact_v
        return self.contact.snapshot(), None if v is None else v.snapshot()

    def _restore(self, saved: tuple[object, object]) -> None:
        self.contact.restore(saved[0])
        if self.contact_v is not None:
            self.contact_v.restore(saved[1])

    def commit(self, t: float) -> None:
        """Integrate exactly to ``t`` and start a new piece there."""
        self.advance(t, exact=True)
        self._anchor = t
        self._grid_changed()

    def _next_breakpoint(self) -> float:
        ends = [b for b in (self.spin.ramp_end, self.lift.end) if b > self._anchor]
        return min(ends, default=math.inf)

    def _step(self, a: float, b: float) -> float:
        end = b if math.isfinite(b) else a + 1.0
        rate = self.spin.peak_speed(a, end) * self.cfg.arm + self.lift.rate(a, end)
        if rate <= 0:
            return self.cfg.max_substep
        return min(self.cfg.max_substep, self.cfg.substep_travel / rate)

    def _sample_times(self, lo: float, hi: float) -> FloatArray:
        if self._stream is None:
            return np.empty(0)
        t_start, interval, k_next = self._stream
        k_hi = math.floor((hi - t_start) / interval + 1e-9)
        if k_hi < k_next:
            return np.empty(0)
        times = t_start + interval * np.arange(k_next, k_hi + 1, dtype=np.float64)
        return times[(times > lo) & (times <= hi)]

    def advance(self, t: float, exact: bool = False, ahead: bool = False) -> None:
        """Integrate every grid node up to ``t`` (and ``t`` itself if ``exact``).

        ``ahead`` (a streaming read): integrate up to ``t + LOOKAHEAD`` in one pass and hand
        out the samples up to ``t``; the next reads are then served from what was integrated.
        The nodes are those of the grid either way (fixed by the motion and the stream), so
        only the blocks the contact is stepped in differ (rounding, docs/decisions/0090).
        Anything else (a command, a single reading, the stream started or
        stopped) first returns to the last node before the look-ahead.
        """
        ahead = ahead and not exact
        if self._ahead is not None:
            if ahead and t <= self._ahead.until:
                self._release(t)
                return
            if ahead:  # every held sample is due: continue from where the look-ahead ended
                self._release(math.inf)
                self._ahead = None
            else:
                self._rewind()
        if not exact and t <= self._covered:
            return  # every node up to t is integrated; the grid has not changed since
        if ahead and self._stream is not None and not self._ahead_off and self._look_ahead(t):
            return
        self._integrate_to(t, exact)
        if not exact:
            self._covered = t

    def _look_ahead(self, t: float) -> bool:
        """Integrate to ``t + LOOKAHEAD`` collecting samples aside; False (state unchanged)
        if a block came beyond a limit (a trip is then found without look-ahead)."""
        until = t + LOOKAHEAD
        start = (self.t_int, self._anchor, self._prev, self._save(), self._stream)
        self._pending = _Ahead(start, until)
        try:
            self._integrate_to(until, exact=False)
        except _Abandon:
            self._return_to(start)
            self._ahead_off = True
            return False
        finally:
            ahead, self._pending = self._pending, None
        self._ahead = ahead
        self._stream = start[4]  # the stream index advances as samples are handed out
        self._covered = until
        self._release(t)
        return True

    def _release(self, t: float) -> None:
        """Move the held samples up to ``t`` into ``samples`` (with the overflow rule)."""
        a = self._ahead
        assert a is not None and self._stream is not None
        i = bisect_right(a.times, t, lo=a.released)
        if i == a.released:
            return
        self.samples.extend(a.samples[a.released:i])
        t_start, interval, _ = self._stream
        k_next = a.ks[i - 1] + 1
        self._stream = (t_start, interval, k_next)
        # A grid node within rounding of a sample time is a sample too (two of one index);
        # one integrated after a read is not (its index is below the stream's next): as
        # without look-ahead, a read between the two keeps only the first.
        while i < len(a.ks) and a.ks[i] < k_next:
            i += 1
        a.released = i
        excess = len(self.samples) - self.cfg.stream_buffer
        if excess > 0:
            del self.samples[:excess]
            self.overflowed = True

    def _rewind(self) -> None:
        """Back to the state before the look-ahead; samples handed out stay handed out."""
        a = self._ahead
        assert a is not None
        self._ahead = None
        if self._stream is not None:
            self._drop_k = self._stream[2]
        self._return_to(a.start)

    def _return_to(self, start: tuple[float, float, tuple[float, float, float],
                                       tuple[object, object],
                                       tuple[float, float, int] | None]) -> None:
        self.t_int, self._anchor, self._prev, saved, self._stream = start
        self._restore(saved)
        self._covered = -math.inf

    def _integrate_to(self, t: float, exact: bool) -> None:
        while self.t_int < t:
            a = self._anchor
            b = self._next_breakpoint()
            dt = self._step(a, b)
            k0 = math.floor((self.t_int - a) / dt) + 1
            wanted = math.floor((min(b, t) - a) / dt) - k0 + 2 if math.isfinite(t) else CHUNK
            grid = a + dt * np.arange(k0, k0 + min(CHUNK, max(wanted, 0)), dtype=np.float64)
            grid = grid[(grid > self.t_int) & (grid < b) & (grid <= t)]
            full = grid.size == CHUNK
            reach_b = not full and b <= t
            upper = float(grid[-1]) if full else (b if reach_b else t)
            parts = [grid, self._sample_times(self.t_int, upper)]
            if reach_b:
                parts.append(np.array([b]))
            elif exact and not full:
                parts.append(np.array([t]))
            nodes = _sorted_unique(np.concatenate(parts))
            nodes = nodes[nodes > self.t_int]
            if nodes.size:
                self._integrate(nodes)
            if self._anchor != a:  # a trip started a new piece
                continue
            if reach_b:
                self._anchor = b
            if not full and not reach_b:
                break

    def _integrate(self, nodes: FloatArray) -> None:
        phi, omega = self.spin.at(nodes)
        gap = self.lift.at(nodes)
        x, h = self.geometry(phi, gap)
        delta = self.cfg.s - np.hypot(h, x)
        saved = self._save()
        f_perp = self.contact.block(nodes, delta)
        f_perp_v = None if self.contact_v is None else self.contact_v.block(nodes, delta)
        _, f_v, torque = self._resolve(f_perp, x, h, omega, f_perp_v)
        abs_fv, abs_m = np.abs(f_v), np.abs(torque)
        cfg = self.cfg
        n = nodes.size
        # A limit trips only where a value is beyond it: a block within every limit (the
        # usual case) needs no comparison with the previous node. (NaN takes the full check.)
        within = (float(delta.max()) <= cfg.overlap_limit
                  and float(abs_fv.max()) <= cfg.normal_force_range
                  and float(abs_m.max()) <= cfg.torque_range)
        tripped = np.empty(0, dtype=np.intp)
        if not within and self._pending is not None:
            raise _Abandon
        if not within:
            p_delta, p_fv, p_m = (
                np.concatenate(([p], v[:-1]))
                for p, v in zip(self._prev, (delta, abs_fv, abs_m), strict=True)
            )
            over = ((delta > cfg.overlap_limit) & (delta > p_delta)) | (
                (abs_fv > cfg.normal_force_range) & (abs_fv > p_fv)
            )
            over_t = (abs_m > cfg.torque_range) & (abs_m > p_m)
            tripped = np.flatnonzero(over | over_t)
        if tripped.size:
            i = int(tripped[0])
            n = i + 1
            self._restore(saved)
            self.contact.block(nodes[:n], delta[:n])
            if self.contact_v is not None:
                self.contact_v.block(nodes[:n], delta[:n])
            if over[i]:
                detail = f"normal force overload at overlap {delta[i] * 1e3:.3f} mm"
                code = TRIP_OVERLOAD
            else:
                detail = f"torque over range ({torque[i] * 1e3:.4f} mN m)"
                code = TRIP_TORQUE
            trip = Trip(code, float(nodes[i]), detail, float(phi[i]), float(gap[i]))
            self.trips.append(trip)
            t_trip = float(nodes[i])
            self.spin = self.spin.halt(t_trip)
            self.lift = self.lift.halt(t_trip)
            self._anchor = t_trip
            self._covered = -math.inf
        self.t_int = float(nodes[n - 1])
        self._prev = (float(delta[n - 1]), float(abs_fv[n - 1]), float(abs_m[n - 1]))
        self._record(nodes[:n], phi[:n], torque[:n], f_v[:n], gap[:n])

    def _record(
        self, t: FloatArray, phi: FloatArray, torque: FloatArray, f_v: FloatArray, gap: FloatArray
    ) -> None:
        if self._stream is None:
            return
        t_start, interval, k_next = self._stream
        k = np.rint((t - t_start) / interval)
        # np.isclose(t, t_start + k interval, rtol=0, atol) without its generality: finite
        # times, |a - b| <= atol.
        atol = 1e-9 * max(1.0, interval)
        hit = np.flatnonzero((k >= k_next) & (np.abs(t - (t_start + k * interval)) <= atol))
        if hit.size:
            k_last = int(k[hit[-1]]) + 1
            if k_next < self._drop_k:  # after a rewind: handed out already
                hit = hit[k[hit] >= self._drop_k]
            self._stream = (t_start, interval, k_last)
        if hit.size:
            new = map(_as_sample, zip((t[hit] - t_start).tolist(), phi[hit].tolist(),
                                      torque[hit].tolist(), f_v[hit].tolist(),
                                      gap[hit].tolist(), strict=True))
            held = self._pending
            if held is not None:
                held.samples.extend(new)
                held.times.extend(t[hit].tolist())
                held.ks.extend(k[hit].astype(np.int64).tolist())
                return
            self.samples.extend(new)
        excess = len(self.samples) - self.cfg.stream_buffer
        if excess > 0:
            del self.samples[:excess]
            self.overflowed = True
