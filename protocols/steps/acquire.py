"""Force acquisition on the compression rig while the stage moves or dwells.

Every wait of a compression step reads the DAQ (the acquisition never falls behind), and each
block is stamped with the plate position at each sample's time: from the stage's path (the
commanded motion checked against the stage's reports, :class:`StagePath`) when the stage keeps
one, else interpolated between polls; a sample whose position cannot be trusted (a report
that disagrees, a gap in which the stage moved) has ``position_flag`` 1 (issue 24). It is
published
through the step context, which checks the interlocks on every sample. Blocks shrink as the
force nears a watched level (a threshold or an interlock limit), down to one sample, so a
crossing is seen within one sample period of happening.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import ClassVar

import numpy as np

from gelrig.instrument.contracts.loadcell import ForceBlock, ForceOverRangeError
from gelrig.instrument.core.noise import MIN_SAMPLES, robust_sigma
from gelrig.instrument.core.stage_path import StagePath
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import CompressionRig

#: Stage polls kept to stamp samples with the plate position.
_POLLS = 256
#: Longest backlog (s of samples) drained in one read when the loop has fallen behind.
_MAX_CATCH_UP = 5.0
#: Samples kept to estimate the force's noise and trend for the look-ahead.
_RECENT = 64

COLUMNS = {"t_s": "s", "position_m": "m", "delta_m": "m", "force_N": "N", "over_range": "1",
           "position_flag": "1"}
#: Without a stage path: polls farther apart than this (s) across which the stage moved leave
#: the interpolated positions between them flagged.
_MAX_POLL_GAP = 2.0


class ForceRecorder:
    """Reads force blocks, stamps them with the plate position, publishes, keeps a copy."""

    #: the columns it publishes, with units: what a step using it declares as its ``columns``
    columns_published: ClassVar[dict[str, str]] = COLUMNS

    def __init__(self, ctx: StepContext[CompressionRig], rate: float,
                 first_touch: float = math.nan, block_time: float = 0.1, keep: bool = True):
        rig = ctx.rig
        self.ctx = ctx
        self.rig = rig
        self.rate = rate
        self.first_touch = first_touch
        self.n_max = max(1, round(rate * block_time))
        self.keep = keep
        self.kept: dict[str, list[FloatArray]] = {k: [] for k in COLUMNS}
        self._polls_t: FloatArray = np.empty(0)
        self._polls_z: FloatArray = np.empty(0)
        self._last_f = math.nan
        self._last_t: float | None = None
        self._last_volts: FloatArray = np.empty(0)
        self._recent: FloatArray = np.empty(0)  # the latest forces, for noise and trend

    def start(self) -> None:
        force = self.rig.force
        try:
            running = abs(force.rate - self.rate) < 1e-9
        except Exception:
            running = False
        if not running:
            force.start(self.rate)
        self._poll()

    def _poll(self) -> None:
        before = self.ctx.clock.now()
        z = self.rig.stage.position()
        t = 0.5 * (before + self.ctx.clock.now())  # the reply's likely moment
        self._polls_t = np.append(self._polls_t[-(_POLLS - 1):], t)
        self._polls_z = np.append(self._polls_z[-(_POLLS - 1):], z)

    def _block_size(self, watch: tuple[float, ...], n_max: int) -> int:
        """Samples that can be read before a watched level could be crossed (halved for
        safety); one sample once the force is within 5 sigma of a level."""
        recent = self._recent
        if recent.size < MIN_SAMPLES:
            return 1 if watch else n_max
        last = float(recent[-1])
        sigma = robust_sigma(recent)
        k = max(1, recent.size // 4)
        slope = (float(recent[-k:].mean()) - float(recent[:k].mean())) / (recent.size - k)
        room = min((w - last for w in watch), default=math.inf)
        if math.isinf(room):
            return n_max
        room -= 5.0 * sigma
        if room <= 0:
            return 1
        if slope <= 0:
            return n_max
        return int(min(n_max, max(1, math.floor(room / slope / 2))))

    def read(
        self, watch: tuple[float, ...] = (), n_max: int | None = None
    ) -> dict[str, FloatArray]:
        """Read, stamp and publish one block (at most ``n_max`` samples); returns its columns."""
        self.ctx.tick()
        limits = tuple(il.limit for il in self.ctx.interlocks if il.column == "force_N")
        cap = n_max or self.n_max
        n = self._block_size(watch + limits, cap)
        if n == cap and self._last_t is not None:
            # Behind the sample clock (paced or real time)? Drain the backlog in one read.
            backlog = math.floor((self.ctx.clock.now() - self._last_t) * self.rate)
            n = max(n, min(backlog, round(self.rate * _MAX_CATCH_UP)))
        try:
            block = self.rig.force.read_block(n)
            over: ForceOverRangeError | None = None
        except ForceOverRangeError as exc:  # keep the flagged data, then stop
            block, over = exc.block, exc
        data = self._stamp(block)
        if self.keep:
            for k, v in data.items():
                self.kept[k].append(v)
        self.ctx.emit(data)
        if over is not None:
            self.rig.stop_all()
            raise over
        return data

    def tare(self, duration: float) -> float:
        """Zero the force on ``duration`` s of samples, which are recorded like any others
        (they carry the previous zero); returns the removed offset (N)."""
        want = max(1, round(duration * self.rate))
        volts: list[FloatArray] = []
        got = 0
        while got < want:
            self.read(n_max=want - got)
            volts.append(self._last_volts)
            got += self._last_volts.size
        return self.rig.force.zero_on(np.concatenate(volts))

    def _stamp(self, block: ForceBlock) -> dict[str, FloatArray]:
        self._poll()
        z, flag = self._positions(np.asarray(block.t, dtype=float))
        self._last_volts = np.asarray(block.volts, dtype=float)
        if len(block):
            self._last_t = float(block.t[-1])
            self._recent = np.concatenate((self._recent, block.force))[-_RECENT:]
            self._last_f = float(block.force[-1])
        return {
            "t_s": np.asarray(block.t, dtype=float),
            "position_m": z,
            "delta_m": z - self.first_touch,
            "force_N": np.asarray(block.force, dtype=float),
            "over_range": np.asarray(block.over_range, dtype=float),
            "position_flag": flag,
        }

    def _positions(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Plate positions at the sample times ``t`` and their flags (1: untrusted)."""
        if not t.size:
            return np.empty(0), np.empty(0)
        path = getattr(self.rig.stage, "path", None)
        if isinstance(path, StagePath):
            z, flag = path.positions(t)
            return z, flag.astype(float)
        # A stage that keeps no path: interpolate over the recent polls (the loop may lag
        # the samples), flagging the spans between polls far apart across which it moved.
        pt, pz = self._polls_t, self._polls_z
        z = np.interp(t, pt, pz)
        if pt.size < 2:
            return z, np.zeros(t.shape)
        i = np.clip(np.searchsorted(pt, t), 1, pt.size - 1)
        gap = (pt[i] - pt[i - 1] > _MAX_POLL_GAP) & (pz[i] != pz[i - 1])
        return z, gap.astype(float)

    def until_stopped(self, watch: tuple[float, ...] = (),
                      stop_above: float | None = None) -> int | None:
        """Read blocks until the stage stops; with ``stop_above`` stop it at once when the force
        first exceeds that level and return the sample's index in ``kept`` order, else None."""
        seen = sum(len(v) for v in self.kept["t_s"])
        while True:
            data = self.read(watch)
            if stop_above is not None:
                over = np.flatnonzero(data["force_N"] > stop_above)
                if over.size:
                    self.rig.stage.stop(immediate=True)
                    self._drain_motion()
                    return seen + int(over[0])
            seen += len(data["t_s"])
            if not self.rig.stage.is_moving():
                self._catch_up(self.ctx.clock.now())
                return None

    def _drain_motion(self) -> None:
        while self.rig.stage.is_moving():
            self.read()
        self._catch_up(self.ctx.clock.now())

    def _catch_up(self, t: float) -> None:
        """Read until the samples reach time ``t``: when the loop lags the sample clock
        (paced or real time), a motion is over only once its samples are all in, so none
        of them spill into whatever comes next."""
        while self._last_t is not None and self._last_t < t - 1.0 / self.rate:
            self.read()

    def dwell(self, duration: float, progress: bool = False, label: str = "",
              block_time: float = 4.0, endable: bool = False,
              after_block: Callable[[dict[str, FloatArray]], bool] | None = None) -> float:
        """Keep reading for ``duration`` seconds of clock time, in blocks of up to
        ``block_time`` (nothing moves, so blocks can be long; they still shrink near a limit).
        ``endable``: a hold a person may end early (``RunControl.end_hold``: at the end of
        the current block, its data kept). ``after_block`` sees every block read and ends the
        dwell by returning True (an adaptive hold). Returns the clock time it lasted."""
        clock = self.ctx.clock
        control = self.ctx.control
        start = clock.now()
        end = start + duration
        next_report = start
        n_hold = max(1, round(self.rate * block_time))
        if endable:
            control.enter_hold()
        try:
            while clock.now() < end and not (endable and control.hold_end_requested):
                remaining = max(1, math.ceil((end - clock.now()) * self.rate))
                data = self.read(n_max=min(n_hold, remaining))
                if after_block is not None and after_block(data):
                    break
                now = clock.now()
                if progress and now >= next_report:
                    self.ctx.progress((now - start) / duration, now - start, end - now, label,
                                      force_N=self._last_f)
                    next_report = now + duration / 200
        finally:
            if endable:
                control.leave_hold()
        return clock.now() - start

    def columns(self) -> dict[str, FloatArray]:
        """Everything kept so far, concatenated."""
        return {k: np.concatenate(v) if v else np.empty(0) for k, v in self.kept.items()}

    def clear(self) -> None:
        self.kept = {k: [] for k in COLUMNS}
