"""Moving the rheometer arm and recording its measurement stream, for the shear steps."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from gelrig.instrument.contracts.bounded_motion import keep_moving
from gelrig.instrument.contracts.rheometer import Rheometer, StreamBlock, StreamPoint
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import ShearRig

COLUMNS = {
    "t_s": "s", "angle_rad": "rad", "theta_m": "m", "torque_Nm": "N*m",
    "normal_force_N": "N", "gap_m": "m", "pass": "1", "direction": "1", "speed_m_s": "m/s",
    "overlap_m": "m",
}


class ArmRecorder:
    """Streams points while the arm turns or rests, publishes them with pass labels."""

    #: the columns it publishes, with units: what a step using it declares as its ``columns``
    columns_published: ClassVar[dict[str, str]] = COLUMNS

    def __init__(self, ctx: StepContext[ShearRig], interval: float, read_period: float = 1.0):
        rig = ctx.rig
        self.ctx = ctx
        self.rheo: Rheometer = rig.rheometer
        self.arm = self.rheo.config.arm
        self.interval = interval
        self.read_period = max(read_period, interval)
        self.labels = {"pass": -1.0, "direction": 0.0, "speed_m_s": 0.0, "overlap_m": math.nan}
        self.kept: list[dict[str, FloatArray]] = []
        self.keep = False
        self._trend: dict[str, tuple[float, float]] = {}  # column -> (last |value|, rate /s)
        self.rheo.start_stream(interval)

    def _publish(self, points: Sequence[StreamPoint]) -> dict[str, FloatArray] | None:
        if not points:
            return None
        block = StreamBlock.of(points)
        n = len(block)
        data = {"t_s": block.t, "angle_rad": block.angle, "theta_m": block.theta,
                "torque_Nm": block.torque, "normal_force_N": block.normal_force,
                "gap_m": block.gap}
        for key, value in self.labels.items():
            data[key] = np.full(n, value)
        self._update_trend(data)
        if self.keep:
            self.kept.append(data)
        self.ctx.emit(data)
        return data

    def _watched(self, extra: dict[str, float] | None = None) -> list[tuple[str, float]]:
        """(column, level) pairs to watch: the interlocks and any extra levels (thresholds)."""
        levels = [(il.column, il.limit) for il in self.ctx.interlocks]
        return levels + list((extra or {}).items())

    def _update_trend(self, data: dict[str, FloatArray]) -> None:
        t = data["t_s"]
        for column in {c for c, _ in self._watched({"torque_Nm": 0.0})}:
            v = data.get(column)
            if v is None or len(v) == 0:
                continue
            first, last = abs(float(v[0])), abs(float(v[-1]))  # only the ends are used
            prev = self._trend.get(column)
            if len(v) >= 2 and t[-1] > t[0]:
                rate = (last - first) / float(t[-1] - t[0])
            elif prev is not None:
                rate = (last - prev[0]) / max(self.interval, 1e-9)
            else:
                rate = 0.0
            self._trend[column] = (last, rate)

    def next_read(self, watch: dict[str, float] | None = None) -> float:
        """Lab time to the next read: the read period, shortened to one stream interval when
        a watched quantity (an interlock's column, or an extra level such as a search
        threshold) could reach its level before then, so a crossing is seen within one
        sample."""
        for column, level in self._watched(watch):
            last, rate = self._trend.get(column, (0.0, 0.0))
            room = level - last
            if room <= 0 or (rate > 0 and room / rate < 2 * self.read_period) \
                    or last > 0.5 * level:
                return self.interval
        return self.read_period

    def poll(self) -> dict[str, FloatArray] | None:
        self.ctx.tick()
        return self._publish(self.rheo.read_stream())

    def dwell(self, duration: float) -> None:
        clock = self.ctx.clock
        end = clock.now() + duration
        while clock.now() < end - 1e-12:
            clock.sleep(min(self.next_read(), end - clock.now()))
            self.poll()

    def turn_to(self, angle: float, speed: float,
                stop_above: float | None = None) -> float | None:
        """Turn at ``|speed|`` (m/s at the arm) until ``angle`` (rad); with ``stop_above`` stop
        early when ``|torque|`` exceeds it and return the angle there, else None."""
        start = self.rheo.angle()
        direction = 1.0 if angle > start else -1.0
        if abs(angle - start) * self.arm < 1e-9:
            return None
        self.rheo.rotate(direction * abs(speed))
        hit: float | None = None
        try:
            while True:
                data = self.poll()
                if stop_above is not None and data is not None:
                    over = np.flatnonzero(np.abs(data["torque_Nm"]) > stop_above)
                    if over.size:
                        hit = float(data["angle_rad"][over[0]])
                        break
                now_angle = self.rheo.angle()
                remaining = (angle - now_angle) * direction * self.arm
                if remaining <= 0:
                    break
                watch = {"torque_Nm": stop_above} if stop_above is not None else None
                step = min(remaining / abs(speed), self.next_read(watch))
                self._turning_sleep(max(step, self.interval))
        finally:
            self.rheo.stop()
        self.settle()
        return hit

    def _turning_sleep(self, duration: float) -> None:
        """Sleep ``duration`` while the arm turns, renewing its rotation (ADR 0201): a wait
        between reads may be longer than the rotation lasts on the instrument."""
        keep_moving(self.ctx.clock, self.rheo, duration, self.rheo.config.motion_bound)

    def settle(self, timeout: float = 30.0) -> None:
        """Poll until the arm is at rest after a stop."""
        clock = self.ctx.clock
        end = clock.now() + timeout
        while self.rheo.status().busy and clock.now() < end:
            clock.sleep(self.interval)
            self.poll()
        self.poll()

    def close(self) -> None:
        try:
            self.poll()
        finally:
            self.rheo.stop_stream()

    def columns(self) -> dict[str, FloatArray]:
        if not self.kept:
            return {k: np.empty(0) for k in COLUMNS}
        return {k: np.concatenate([d[k] for d in self.kept]) for k in COLUMNS}
