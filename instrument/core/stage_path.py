"""Where the stage was between its reports: the commanded motion, checked against the reports.

A KDC101 reports its position when polled or in a status message; between two reports the
stage may have started, cruised and stopped, so a straight line between reports is wrong
across such a gap (issue 24). :class:`StagePath` rebuilds the path from what was commanded:
each move's start, speed and acceleration (the controller's trapezoid,
:mod:`gelrig.instrument.core.motion`) and each stop, and checks every report against it. A
command or a report is an instant known only to lie in a window ``[lo, hi]`` of the run's
clock (the write of the command; a poll's request and reply); reports narrow the moment a move
started (every position passed while moving pins it) and the moment an immediate stop took
effect (the position it stopped at).

Where the path cannot be trusted its samples are flagged, never silently filled:

- between two reports, when the later one disagrees with the path by more than
  ``tolerance``;
- while moving, when the move's start is uncertain by more than ``max_error`` of travel;
- while moving, between reports more than ``max_gap`` apart;
- after a motion the driver cannot describe (homing, a disable) until the next report.

Times in s, positions in m (the driver's axis).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from gelrig.instrument.core.motion import Phase, Trajectory, plan_move, plan_stop
from gelrig.instrument.core.timebase import TimeMapping

FloatArray = NDArray[np.float64]

#: Segments (commands) and reports a path keeps: far more than a force block looks back.
KEEP_SEGMENTS = 256
KEEP_REPORTS = 4096


@dataclass
class _Segment:
    """What happened from one moment on: ``kind`` "anchor" (at ``x`` with speed ``v``),
    "move" (to ``target`` at ``speed``, ``accel``), "halt" (immediate stop), "stop"
    (profiled) or "lost" (an unknown motion). It took effect at ``t``, known to lie in
    [``lo``, ``hi``] (narrowed by reports)."""

    kind: str
    lo: float
    hi: float
    t: float
    target: float = math.nan
    speed: float = math.nan
    accel: float = math.nan
    x: float = math.nan
    v: float = 0.0
    refined: bool = False
    #: the state the segment started from (set when the path is rebuilt)
    x0: float = math.nan
    v0: float = 0.0
    before: Trajectory | None = field(default=None, repr=False)


@dataclass(frozen=True)
class PathReport:
    """One position report: ``x`` (m) at an instant in [``lo``, ``hi``] (s); ``source``
    "poll" (a request's reply) or "update" (a status update the controller sent by itself)."""

    lo: float
    hi: float
    x: float
    source: str = "poll"

    @property
    def t(self) -> float:
        return 0.5 * (self.lo + self.hi)


class StagePath:
    """The stage's path on the run's clock, from the commanded motion checked against reports.

    ``tolerance`` (m): largest disagreement of a report with the path (a few encoder counts);
    ``max_error`` (m): largest travel the uncertainty of a move's start may amount to;
    ``max_gap`` (s): longest span between reports over which a moving path is trusted;
    ``command_slack`` (s): how long after its write returned a command may take effect (the
    link's latency).
    """

    def __init__(self, tolerance: float = 2e-7, max_error: float = 2e-6, max_gap: float = 2.0,
                 command_slack: float = 0.002):
        self.tolerance = tolerance
        self.max_error = max_error
        self.max_gap = max_gap
        self.command_slack = command_slack
        self._segments: list[_Segment] = []
        self._reports: deque[PathReport] = deque(maxlen=KEEP_REPORTS)
        self._flagged: deque[tuple[float, float]] = deque(maxlen=KEEP_REPORTS)
        self._traj: Trajectory | None = None
        self._dirty = True
        self.disagreements = 0

    # ---- what the driver tells it ---------------------------------------------------------
    def commanded(self, lo: float, hi: float, target: float, speed: float, accel: float
                  ) -> None:
        """A move to ``target`` (m) at ``speed`` (m/s), ``accel`` (m/s^2), written in
        [lo, hi]."""
        self._add(_Segment("move", lo, hi + self.command_slack, 0.5 * (lo + hi),
                           target=target, speed=speed, accel=accel))

    def stopped(self, lo: float, hi: float, immediate: bool, accel: float = math.nan) -> None:
        """A stop written in [lo, hi]: immediate, or profiled at ``accel``."""
        self._add(_Segment("halt" if immediate else "stop", lo, hi + self.command_slack,
                           0.5 * (lo + hi), accel=accel))

    def lost(self, t: float) -> None:
        """From ``t`` the stage moves in a way the path cannot describe (homing, a disable):
        flagged until the next report, which anchors the path again."""
        self._add(_Segment("lost", t, t, t))

    def reported(self, lo: float, hi: float, x: float, source: str = "poll") -> None:
        """The stage was at ``x`` (m) at an instant in [lo, hi] (``source``: "poll" or
        "update")."""
        report = PathReport(lo, hi, x, source)
        previous = self._reports[-1] if self._reports else None
        self._reports.append(report)
        last = self._segments[-1] if self._segments else None
        if last is None or last.kind == "lost":
            if last is not None:
                self._flagged.append((last.t, hi))
            self._add(_Segment("anchor", report.t, report.t, report.t, x=x))
            return
        self._refine(last, report)
        err = self._disagreement(report)
        if err > self.tolerance:
            self.disagreements += 1
            self._flagged.append((previous.hi if previous is not None else lo, hi))
            if self._restart(last, report):
                return  # the commanded move goes on, its start placed by this report
            traj = self._trajectory()
            v = traj.velocity_at(report.t)
            # re-anchor on the report: at rest if the path says so, else lost until a report
            # finds the stage where the path can start again
            self._add(_Segment("anchor", report.t, report.t, report.t, x=x) if v == 0.0
                      else _Segment("lost", report.t, report.t, report.t))

    # ---- what the recorder asks -----------------------------------------------------------
    def positions(self, ts: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Positions (m) at times ``ts`` and a flag per sample (True: not to be trusted)."""
        ts = np.asarray(ts, dtype=float)
        flags = np.zeros(ts.shape, dtype=bool)
        if not self._segments:
            return np.full(ts.shape, np.nan), ~flags
        traj = self._trajectory()
        z = traj.positions_at(ts)
        flags |= (ts < self._segments[0].t) | ~np.isfinite(z)
        for a, b in self._flagged:
            flags |= (ts > a) & (ts <= b)
        for seg in self._segments:
            if seg.kind == "lost":
                nxt = next((r.hi for r in self._reports if r.lo > seg.t), math.inf)
                flags |= (ts >= seg.t) & (ts <= nxt)
        moving = self._moving(traj, ts)
        if moving.any():
            flags |= moving & self._uncertain(ts)
            flags |= moving & self._in_long_gap(ts)
        return z, flags

    def position(self, t: float) -> float:
        """The path's position (m) at ``t``."""
        return float(self._trajectory().position_at(t))

    def uncertainty(self) -> float:
        """Largest travel (m) the uncertainty of a kept move's start amounts to."""
        return max((0.5 * (s.hi - s.lo) * s.speed for s in self._segments if s.kind == "move"),
                   default=0.0)

    def mapping(self, instrument: str = "stage") -> TimeMapping:
        """What run.json says of how the stage's positions are put on the run's clock."""
        windows = np.array([r.hi - r.lo for r in self._reports]) if self._reports else None
        gaps = np.diff([r.t for r in self._reports]) if len(self._reports) > 1 else None
        updates = [r for r in self._reports if r.source == "update"]
        u_windows = np.array([r.hi - r.lo for r in updates])
        u_gaps = np.diff([r.t for r in updates])
        moves = [s for s in self._segments if s.kind == "move"]
        start = max((0.5 * (s.hi - s.lo) for s in moves), default=0.0)
        return TimeMapping(
            instrument, "positions between reports from the commanded motion (trapezoid from "
            "each move's start, speed and acceleration; stops solved from the position "
            "reached), checked against each poll's reply, taken within its request-reply "
            "window, and each status update, taken within its arrival window", start,
            {"reports_kept": len(self._reports),
             "report_window_median_s": float(np.median(windows)) if windows is not None
             else None,
             "report_window_max_s": float(windows.max()) if windows is not None else None,
             "report_interval_median_s": float(np.median(gaps)) if gaps is not None
             else None,
             "report_interval_max_s": float(gaps.max()) if gaps is not None else None,
             "updates_kept": len(updates),
             "update_window_median_s": float(np.median(u_windows)) if updates else None,
             "update_window_max_s": float(u_windows.max()) if updates else None,
             "update_interval_median_s": float(np.median(u_gaps)) if u_gaps.size else None,
             "move_start_uncertainty_max_s": start,
             "position_uncertainty_max_m": self.uncertainty(),
             "disagreements": self.disagreements, "tolerance_m": self.tolerance,
             "max_error_m": self.max_error, "max_gap_s": self.max_gap})

    # ---- inside ---------------------------------------------------------------------------
    def _add(self, seg: _Segment) -> None:
        if len(self._segments) >= KEEP_SEGMENTS:
            keep = self._segments[-(KEEP_SEGMENTS // 2):]
            traj = self._trajectory()
            t = keep[0].lo
            keep.insert(0, _Segment("anchor", t, t, t, x=traj.position_at(t),
                                    v=traj.velocity_at(t)))
            self._segments = keep
        self._segments.append(seg)
        self._dirty = True

    def _trajectory(self) -> Trajectory:
        if self._dirty or self._traj is None:
            self._traj = self._rebuild()
            self._dirty = False
        return self._traj

    def _rebuild(self) -> Trajectory:
        traj: Trajectory | None = None
        for seg in self._segments:
            t = seg.t
            if traj is None:
                seg.x0, seg.v0 = seg.x, seg.v
                traj = Trajectory(seg.x if seg.kind == "anchor" else math.nan, t)
                if seg.v:
                    traj.replace_from(t, [Phase(t, seg.x, seg.v, 0.0)])
                continue
            x, v = traj.position_at(t), traj.velocity_at(t)
            seg.x0, seg.v0 = x, v
            if seg.kind == "anchor":
                phases = [Phase(t, seg.x, seg.v, 0.0)]
            elif seg.kind == "move":
                phases = plan_move(t, x, v, seg.target, seg.speed, seg.accel)
            elif seg.kind == "stop" and math.isfinite(seg.accel):
                phases = plan_stop(t, x, v, seg.accel)
            else:  # a halt, or a stop or loss whose course is unknown: at rest where it was
                phases = [Phase(t, x, 0.0, 0.0)]
            seg.before = traj.copy()
            traj.replace_from(t, phases)
        assert traj is not None
        return traj

    def _refine(self, seg: _Segment, report: PathReport) -> None:
        """Narrow when ``seg`` took effect with ``report`` (see the module's docstring)."""
        if seg.kind not in ("move", "halt") or seg.refined or report.hi <= seg.lo:
            return
        self._trajectory()
        if seg.kind == "halt":
            if report.lo < seg.hi or seg.before is None:
                return  # not surely after the stop took effect
            before = seg.before
            f = lambda t: before.position_at(t) - report.x  # noqa: E731
            lo, hi = seg.lo, seg.hi
            if f(lo) * f(hi) > 0:
                return  # the report is not where the stage could have stopped: checked later
            from scipy.optimize import brentq  # lazy: scipy.optimize costs a start-up
            t = brentq(f, lo, hi, xtol=1e-7) if f(lo) != f(hi) else seg.t
            seg.lo = seg.hi = seg.t = float(t)
            seg.refined = True
            self._dirty = True
            return
        tau = self._time_into(seg, report.x)
        if tau is None:
            return  # at the start or the end: says little about when it started
        lo, hi = max(seg.lo, report.lo - tau), min(seg.hi, report.hi - tau)
        if lo <= hi:
            seg.lo, seg.hi, seg.t = lo, hi, 0.5 * (lo + hi)
            self._dirty = True

    def _restart(self, seg: _Segment, report: PathReport) -> bool:
        """Place the start of the move ``seg`` by ``report`` alone (it disagreed with the
        window the command was written in); False if the report cannot place it."""
        tau = self._time_into(seg, report.x)
        if tau is None:
            return False
        seg.lo, seg.hi = report.lo - tau, report.hi - tau
        seg.t = 0.5 * (seg.lo + seg.hi)
        self._dirty = True
        return self._disagreement(report) <= self.tolerance

    def _time_into(self, seg: _Segment, x: float) -> float | None:
        """How long after its start the move ``seg`` (from rest) passes ``x``; None if it is
        not a move from rest or ``x`` is at its start or end."""
        if seg.kind != "move" or seg.v0 != 0.0 or not math.isfinite(seg.x0):
            return None
        span = seg.target - seg.x0
        if abs(span) <= 2 * self.tolerance:
            return None
        frac = (x - seg.x0) / span
        margin = self.tolerance / abs(span)
        if not margin < frac < 1.0 - margin:
            return None
        profile = plan_move(0.0, seg.x0, 0.0, seg.target, seg.speed, seg.accel)
        from scipy.optimize import brentq  # lazy: scipy.optimize costs a start-up
        return float(brentq(lambda s: _at(profile, s) - x, 0.0, profile[-1].t0, xtol=1e-7))

    def _disagreement(self, report: PathReport) -> float:
        traj = self._trajectory()
        xs = traj.positions_at(np.array([report.lo, report.t, report.hi]))
        return float(max(0.0, xs.min() - report.x, report.x - xs.max()))

    @staticmethod
    def _moving(traj: Trajectory, ts: FloatArray) -> NDArray[np.bool_]:
        dt = 1e-4
        return np.asarray(np.abs(traj.positions_at(ts + dt) - traj.positions_at(ts)) > 0)

    def _uncertain(self, ts: FloatArray) -> NDArray[np.bool_]:
        out = np.zeros(ts.shape, dtype=bool)
        for i, seg in enumerate(self._segments):
            if seg.kind != "move" or 0.5 * (seg.hi - seg.lo) * seg.speed <= self.max_error:
                continue
            end = self._segments[i + 1].t if i + 1 < len(self._segments) else math.inf
            out |= (ts >= seg.lo) & (ts < end)
        return out

    def _in_long_gap(self, ts: FloatArray) -> NDArray[np.bool_]:
        if not self._reports:
            return np.ones(ts.shape, dtype=bool)
        his = np.array([r.hi for r in self._reports])
        los = np.array([r.lo for r in self._reports])
        i = np.searchsorted(his, ts, side="right")  # reports wholly before each sample
        prev = np.where(i > 0, his[np.clip(i - 1, 0, None)], -np.inf)
        nxt = np.where(i < los.size, los[np.clip(i, None, los.size - 1)], np.inf)
        gap = nxt - prev
        # after the latest report the path is the commanded one, checked by the next report
        return np.asarray((gap > self.max_gap) & np.isfinite(nxt))


def _at(phases: list[Phase], t: float) -> float:
    """Position of a list of phases at ``t``."""
    i = max(0, int(np.searchsorted([p.t0 for p in phases], t, side="right")) - 1)
    return phases[i].x(t)


__all__ = ["PathReport", "StagePath"]
