"""Holds wherever they are in a compression record: the plate still, or the force held.

A record of any step (a built-in kind or a user's) with the plate position and the force is
cut into blocks of about :data:`BLOCK_S`; a run of blocks in contact is

- a **relaxation hold** when the plate position stays within the stage's resolution over at
  least ``min_duration`` (the force then relaxes), and otherwise
- a **creep hold** when the force stays within a band of its level over at least
  ``min_duration`` while the plate moves (a feedback holds the force; the overlap creeps).

Still runs are found first: a relaxation hold whose force happens to relax little is still a
relaxation hold. Arrays in, :class:`Segment` out; no knowledge of step kinds.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gelrig.instrument.core.noise import robust_sigma

#: Block length (s) the record is judged in.
BLOCK_S = 1.0
#: A hold lasts at least this long (s) by default.
MIN_DURATION = 20.0
#: In contact: the overlap beyond this (m) and the force beyond this many noise sigmas.
CONTACT_OVERLAP = 1e-6
CONTACT_SIGMAS = 5.0
#: A creep hold's block means stay within this fraction of the held force (or 6 block sigmas).
FORCE_BAND = 0.03
#: A creep hold moves the plate by more than this many position tolerances.
CREEP_MOVES = 10.0


@dataclass(frozen=True)
class Segment:
    """A hold: ``kind`` ("relaxation" or "creep"), samples ``[start, end)``, its start time
    (s), duration (s) and held level (plate position in m, or force in N)."""

    kind: str
    start: int
    end: int
    t0: float
    duration: float
    level: float


def _blocks(t: np.ndarray, block: float) -> np.ndarray:
    """Sample index edges of blocks of about ``block`` seconds."""
    if t.size < 2:
        return np.array([0, t.size])
    n = max(1, math.floor((t[-1] - t[0]) / block))
    edges = np.searchsorted(t, t[0] + block * np.arange(n + 1))
    edges[-1] = t.size
    return np.unique(edges)


def find_holds(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    delta: ArrayLike | None = None,
    resolution: float = 1e-8,
    min_duration: float = MIN_DURATION,
) -> list[Segment]:
    """Every relaxation and creep hold of a record, in time order.

    ``t`` (s), plate ``position`` (m), ``force`` (N) and the ``delta`` overlap (m, optional:
    without it contact is judged by the force alone, at twice the sigmas); ``resolution`` (m)
    the stage's position step: a still plate stays within twice it.
    """
    tt = np.asarray(t, dtype=float)
    z = np.asarray(position, dtype=float)
    f = np.asarray(force, dtype=float)
    d = None if delta is None else np.asarray(delta, dtype=float)
    if tt.size < 3 or not np.isfinite(tt).all():
        return []
    sigma = robust_sigma(f[np.isfinite(f)])
    sigma = sigma if math.isfinite(sigma) else 0.0
    edges = _blocks(tt, BLOCK_S)
    spans = [(int(a), int(b)) for a, b in itertools.pairwise(edges)]
    tol = 2.0 * resolution + 1e-12
    zlo, zhi, fmean, inside, ns = [], [], [], [], []
    for a, b in spans:
        zb, fb = z[a:b], f[a:b]
        zlo.append(float(np.nanmin(zb)))
        zhi.append(float(np.nanmax(zb)))
        fm = float(np.nanmean(fb))
        fmean.append(fm)
        ns.append(b - a)
        touching = fm > (CONTACT_SIGMAS if d is not None else 2 * CONTACT_SIGMAS) * sigma
        if d is not None:
            db = d[a:b][np.isfinite(d[a:b])]
            touching = touching and db.size > 0 and float(db.min()) > CONTACT_OVERLAP
        inside.append(touching and math.isfinite(fm))
    used = [False] * len(spans)
    out: list[Segment] = []

    def segment(kind: str, i: int, j: int, level: float) -> Segment | None:
        a, b = int(spans[i][0]), int(spans[j][1])
        duration = float(tt[b - 1] - tt[a])
        if duration < min_duration:
            return None
        for k in range(i, j + 1):
            used[k] = True
        return Segment(kind, a, b, float(tt[a]), duration, level)

    i = 0
    while i < len(spans):  # still runs: the plate within tol
        if not inside[i] or zhi[i] - zlo[i] > tol:
            i += 1
            continue
        lo, hi, j = zlo[i], zhi[i], i
        while (j + 1 < len(spans) and inside[j + 1] and max(hi, zhi[j + 1])
               - min(lo, zlo[j + 1]) <= tol):
            j += 1
            lo, hi = min(lo, zlo[j]), max(hi, zhi[j])
        found = segment("relaxation", i, j, 0.5 * (lo + hi))
        if found is not None:
            out.append(found)
        i = j + 1
    i = 0
    while i < len(spans):  # force-held runs among the rest, the plate moving
        if not inside[i] or used[i]:
            i += 1
            continue
        total, count, j = fmean[i] * ns[i], ns[i], i
        while j + 1 < len(spans) and inside[j + 1] and not used[j + 1]:
            level = total / count
            band = max(FORCE_BAND * abs(level), 6 * sigma / math.sqrt(max(ns[j + 1], 1)))
            if abs(fmean[j + 1] - level) > band:
                break
            j += 1
            total, count = total + fmean[j] * ns[j], count + ns[j]
        moved = max(zhi[i:j + 1]) - min(zlo[i:j + 1])
        if moved > CREEP_MOVES * tol:
            found = segment("creep", i, j, total / count)
            if found is not None:
                out.append(found)
        i = j + 1
    return sorted(out, key=lambda s: s.start)
