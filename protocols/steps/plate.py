"""What the plate steps (``wait``, ``move``, ``rest``, ``load_unload``, ``creep``) share:
where first touch is, the approach before a ramp, a recorded move, the back-off after, and
the statistics of a force record at rest.

Every motion here is commanded while a :class:`ForceRecorder` reads the force, so the rig's
interlocks see every sample.
"""

from __future__ import annotations

import math
from typing import Any

from gelrig.instrument.core.errors import GelrigError
from gelrig.instrument.core.fields import Field, param
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.caps import stage_position_error
from gelrig.protocols.context import StepContext
from gelrig.protocols.rig import CompressionRig
from gelrig.protocols.steps.acquire import ForceRecorder
from gelrig.protocols.steps.base import StepResult
from gelrig.protocols.steps.compression_search import SearchResult

Ctx = StepContext[CompressionRig]


def first_touch_field() -> Any:
    """The optional ``first_touch`` parameter of a step that works relative to it."""
    return param(Field("first_touch", "m", None, 0.0, 25e-3, optional=True, display="mm",
                       help="stage position of first touch; default: from the contact search "
                            "before"))


def rate_field() -> Any:
    """The ``rate`` parameter: the force sample rate (the USB-6001's range)."""
    return param(Field("rate", "Hz", 100.0, 100.0, 20e3, help="force sample rate"))


def touch_problems(kind: str, first_touch: float | None, span: tuple[float, float],
                   rig: CompressionRig, earlier: tuple[type[StepResult], ...]) -> list[str]:
    """Preflight of a step that works relative to first touch: the positions it commands
    (from ``first_touch + span[0]`` to ``first_touch + span[1]``) within the stage's travel,
    or a contact search before it."""
    if first_touch is None:
        if any(issubclass(r, SearchResult) for r in earlier):
            return []
        return [f"{kind} needs first_touch, or a contact search before it"]
    why = [stage_position_error(first_touch + d, rig.stage_caps) for d in span]
    return [w for w in why if w]


def known_touch(ctx: Ctx, given: float | None) -> float | None:
    """First touch: the parameter, else the latest contact search's, else the rig's."""
    if given is not None:
        return given
    found = ctx.earlier(SearchResult)
    return found.first_touch_m if found is not None else ctx.rig.first_touch


def needed_touch(ctx: Ctx, given: float | None, kind: str) -> float:
    """First touch from the parameter, else from the latest contact search (or refused)."""
    if given is not None:
        return given
    found = ctx.earlier(SearchResult)
    if found is None:
        raise GelrigError(f"{kind} needs first_touch, or a contact search before it")
    return found.first_touch_m


def home_if_needed(ctx: Ctx) -> None:
    """Home the stage first: its positions mean nothing before."""
    if not ctx.rig.stage.status().homed:
        ctx.rig.stage.home(wait=True)


def approach(ctx: Ctx, rec: ForceRecorder, position: float, tare_time: float) -> None:
    """Home if needed, go to ``position`` at the fast speed, tare there, clear the record."""
    rig = ctx.rig
    home_if_needed(ctx)
    rec.start()
    rig.stage.set_velocity(rig.limits.fast_speed, rig.limits.acceleration)
    rig.stage.move_to(position, wait=False)
    rec.until_stopped()
    if tare_time > 0:
        rec.tare(tare_time)
    rec.clear()


def move_recorded(ctx: Ctx, rec: ForceRecorder, target: float, label: str,
                  stop_above: float | None = None) -> int | None:
    """Move the plate to ``target`` at the speed set, reading the force all the way. With
    ``stop_above``: stop at once where the force first exceeds it and return that sample's
    index among those kept (None if it never did)."""
    stage = ctx.rig.stage
    start, t0 = stage.position(), ctx.clock.now()
    stage.move_to(target, wait=False)
    watch = () if stop_above is None else (stop_above,)
    while stage.is_moving():
        data = rec.read(watch)
        if stop_above is not None:
            over = data["force_N"] > stop_above
            if over.any():
                seen = sum(len(v) for v in rec.kept["t_s"]) - len(data["t_s"])
                stage.stop(immediate=True)
                rec.until_stopped()
                return seen + int(over.argmax())
        z = data["position_m"]
        if z.size:
            done = abs(float(z[-1]) - start) / max(abs(target - start), 1e-12)
            ctx.progress(min(done, 1.0), ctx.clock.now() - t0, 0.0, label)
    rec.until_stopped()
    return None


def retract(ctx: Ctx, rec: ForceRecorder, touch: float, back: float) -> None:
    """Back off to ``back`` before first touch at the fast speed (no longer kept)."""
    rig = ctx.rig
    rig.stage.set_velocity(rig.limits.fast_speed, rig.limits.acceleration)
    rig.stage.move_to(max(touch - back, rig.stage_caps.min_position_m), wait=False)
    rec.keep = False
    rec.until_stopped()


def force_stats(cols: dict[str, FloatArray]) -> dict[str, float]:
    """Mean, standard deviation and drift (mean of the last tenth minus mean of the first
    tenth) of a record's force, and its mean plate position."""
    force = cols["force_N"]
    if not force.size:
        return {"position_m": math.nan, "force_mean_N": math.nan, "force_sd_N": math.nan,
                "force_drift_N": math.nan}
    tenth = max(1, force.size // 10)
    return {"position_m": float(cols["position_m"].mean()),
            "force_mean_N": float(force.mean()), "force_sd_N": float(force.std()),
            "force_drift_N": float(force[-tenth:].mean() - force[:tenth].mean())}
