"""The rig file's caps, enforced on every command a step or a manual control sends.

A rig wraps its instruments in these checked views (:class:`CappedStage`,
:class:`CappedRheometer`), so a speed, position or gap outside the rig file's limits is refused
with a :class:`LimitError` that names the cap before the command reaches the instrument:
nothing moves. Everything else passes straight through to the wrapped instrument. What a
rehearsal on the rig's twin passes, a run passes too (docs/decisions/0090). Every call also
passes the rig's fence (:mod:`gelrig.protocols.fence`: safe stop first).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from gelrig.instrument.contracts.rheometer import (
    Rheometer,
    RheometerConfig,
    RheometerStatus,
    StreamPoint,
)
from gelrig.instrument.contracts.stage import Stage, StageConfig, StageStatus
from gelrig.instrument.core.errors import LimitError
from gelrig.instrument.core.identity import Identity
from gelrig.protocols.fence import Fence

T = TypeVar("T")

#: Relative slack on a cap: a speed computed to equal the cap is not refused for rounding.
_SLACK = 1e-9


def stage_speed_error(speed: float, config: StageConfig) -> str | None:
    """Why ``speed`` (m/s) may not be commanded on the stage, or None if it may."""
    cap = config.max_velocity_m_s
    if math.isfinite(speed) and 0 < speed <= cap * (1 + _SLACK):
        return None
    return (f"speed {speed * 1e3:.4g} mm/s above the stage's max_velocity {cap * 1e3:g} mm/s "
            "([stage] max_velocity)" if speed > 0 else f"speed {speed!r} m/s must be > 0")


def stage_position_error(position: float, config: StageConfig) -> str | None:
    """Why the stage may not be sent to ``position`` (m), or None if it may."""
    lo, hi = config.min_position_m, config.max_position_m
    if math.isfinite(position) and lo - 1e-12 <= position <= hi + 1e-12:
        return None
    side = "min_position" if position < lo else "max_position"
    return (f"target {position * 1e3:.4f} mm beyond the stage's travel "
            f"[{lo * 1e3:g}, {hi * 1e3:g}] mm ([stage] {side})")


def arm_speed_error(speed: float, config: RheometerConfig) -> str | None:
    """Why the arm may not turn at ``speed`` (m/s at the arm), or None if it may."""
    cap = config.max_speed
    if math.isfinite(speed) and abs(speed) <= cap * (1 + _SLACK):
        return None
    return (f"arm speed {abs(speed) * 1e3:.4g} mm/s above the rheometer's max_speed "
            f"{cap * 1e3:g} mm/s ([rheometer] max_speed)")


def gap_error(gap: float, config: RheometerConfig, touch_gap: float | None,
              max_overlap: float) -> str | None:
    """Why the lift may not go to ``gap`` (m), or None: within [gap_min, gap_max] and, once
    the touch gap is known, at most ``max_overlap`` below it."""
    if not math.isfinite(gap) or gap > config.gap_max + 1e-12:
        return (f"gap {gap * 1e3:.4g} mm above the rheometer's gap_max "
                f"{config.gap_max * 1e3:g} mm ([rheometer] gap_max)")
    if touch_gap is not None and touch_gap - gap > max_overlap + 1e-12:
        return (f"gap {gap * 1e3:.4g} mm is an overlap of {(touch_gap - gap) * 1e3:.4g} mm "
                f"below the touch gap {touch_gap * 1e3:.4g} mm, beyond the overlap limit "
                f"{max_overlap * 1e3:g} mm ([limits] max_overlap, [rheometer] overlap_limit)")
    if gap < config.gap_min - 1e-12:
        return (f"gap {gap * 1e3:.4g} mm below the rheometer's gap_min "
                f"{config.gap_min * 1e3:g} mm ([rheometer] gap_min): the gap cannot reach it")
    return None


def _refuse(why: str | None) -> None:
    if why is not None:
        raise LimitError(f"{why}; nothing moved")


class CappedStage:
    """A :class:`Stage` with the rig file's caps checked on every command (see module)."""

    def __init__(self, stage: Stage, config: StageConfig, fence: Fence | None = None):
        self.inner = stage
        self.caps = config
        self.fence = fence or Fence()

    def _call(self, what: str, fn: Callable[[], T]) -> T:
        return self.fence.call("stage", what, fn)

    def __getattr__(self, name: str) -> Any:  # driver extras (velocity_params, ...) pass on
        return getattr(self.inner, name)

    def set_velocity(self, max_m_s: float, accel_m_s2: float) -> None:
        _refuse(stage_speed_error(max_m_s, self.caps))
        self._call("set velocity", lambda: self.inner.set_velocity(max_m_s, accel_m_s2))

    def move_to(self, position_m: float, wait: bool = True, timeout: float | None = None) -> None:
        _refuse(stage_position_error(position_m, self.caps))
        self._call("move to", lambda: self.inner.move_to(position_m, wait, timeout))

    def move_by(self, distance_m: float, wait: bool = True, timeout: float | None = None) -> None:
        # the end point is checked by the driver against the same [stage] limits (no extra
        # position query here: it would cost a round trip on every probe)
        self._call("move by", lambda: self.inner.move_by(distance_m, wait, timeout))

    def identify(self) -> Identity:
        return self._call("identify", self.inner.identify)

    def enable(self) -> None:
        self._call("enable", self.inner.enable)

    def home(self, wait: bool = True, timeout: float | None = None) -> None:
        self._call("home", lambda: self.inner.home(wait, timeout))

    def move_velocity(self, direction: int) -> None:
        self._call("move velocity", lambda: self.inner.move_velocity(direction))

    def keep_alive(self) -> None:
        self.inner.keep_alive()

    def stop(self, immediate: bool = True) -> None:
        self._call("stop", lambda: self.inner.stop(immediate))

    def position(self) -> float:
        return self._call("position", self.inner.position)

    def status(self) -> StageStatus:
        return self._call("status", self.inner.status)

    def is_moving(self) -> bool:
        return self._call("is moving", self.inner.is_moving)

    def wait_until_stopped(self, timeout: float | None = None) -> None:
        self._call("wait until stopped", lambda: self.inner.wait_until_stopped(timeout))

    def close(self) -> None:
        self.inner.close()


class CappedRheometer:
    """A :class:`Rheometer` with the rig file's caps checked on every command: the arm's
    speed, and the gap (within the lift's range and, once ``touch_gap`` is known, at most
    ``max_overlap`` below it)."""

    def __init__(self, rheometer: Rheometer, max_overlap: float, fence: Fence | None = None):
        self.inner = rheometer
        self.max_overlap = min(max_overlap, rheometer.config.overlap_limit)
        self.touch_gap: float | None = rheometer.config.touch_gap
        self.fence = fence or Fence()

    def _call(self, what: str, fn: Callable[[], T]) -> T:
        return self.fence.call("rheometer", what, fn)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    @property
    def config(self) -> RheometerConfig:
        return self.inner.config

    def gap_error(self, gap: float) -> str | None:
        """Why the lift may not go to ``gap`` (m), or None."""
        return gap_error(gap, self.inner.config, self.touch_gap, self.max_overlap)

    def rotate(self, speed: float) -> None:
        _refuse(arm_speed_error(speed, self.inner.config))
        self._call("rotate", lambda: self.inner.rotate(speed))

    def keep_alive(self) -> None:
        self.inner.keep_alive()

    def set_gap(self, gap: float, wait: bool = True) -> None:
        _refuse(self.gap_error(gap))
        self._call("set gap", lambda: self.inner.set_gap(gap, wait))

    def identify(self) -> Identity:
        return self._call("identify", self.inner.identify)

    def status(self) -> RheometerStatus:
        return self._call("status", self.inner.status)

    def zero_gap(self) -> None:
        self._call("zero gap", self.inner.zero_gap)

    def gap(self) -> float:
        return self._call("gap", self.inner.gap)

    def stop(self) -> None:
        self._call("stop", self.inner.stop)

    def hold(self) -> None:
        self._call("hold", self.inner.hold)

    def angle(self) -> float:
        return self._call("angle", self.inner.angle)

    def theta(self) -> float:
        return self._call("theta", self.inner.theta)

    def torque(self) -> float:
        return self._call("torque", self.inner.torque)

    def normal_force(self) -> float:
        return self._call("normal force", self.inner.normal_force)

    def start_stream(self, interval: float) -> None:
        self._call("start stream", lambda: self.inner.start_stream(interval))

    def read_stream(self) -> Sequence[StreamPoint]:
        return self._call("read stream", self.inner.read_stream)

    def stop_stream(self) -> None:
        self._call("stop stream", self.inner.stop_stream)

    def close(self) -> None:
        self.inner.close()
