"""``creep``: ramp until the force reaches a target, then hold that force for a while by
moving the stage under feedback, and record how the plate creeps (the overlap growing as the
sphere's modulus relaxes)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gelrig.instrument.core.errors import GelrigError
from gelrig.instrument.core.fields import Field, param
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.caps import stage_speed_error
from gelrig.protocols.rig import CompressionLimits, CompressionRig
from gelrig.protocols.steps.acquire import COLUMNS, ForceRecorder
from gelrig.protocols.steps.base import (
    Limits,
    PlanCheck,
    StepDefinition,
    StepParams,
    StepPlan,
    StepResult,
)
from gelrig.protocols.steps.plate import (
    Ctx,
    approach,
    first_touch_field,
    needed_touch,
    rate_field,
    retract,
    touch_problems,
)


@dataclass(frozen=True)
class CreepParams(StepParams):
    """Parameters of a creep test: the force to hold, for how long, within what tolerance,
    and the feedback."""

    force: float = param(Field("force", "N", 0.1, 0.0, 100.0, lo_open=True, display="mN",
                               help="force held (below [limits] max_force)"))
    hold: float = param(Field("hold", "s", 600.0, 0.0, 7 * 86400.0, lo_open=True,
                              help="time the force is held"))
    tolerance: float = param(Field(
        "tolerance", "N", 2e-3, 0.0, 10.0, lo_open=True, display="mN",
        help="the hold counts as within tolerance when every feedback period's mean force "
             "is this close to the target"))
    speed: float = param(Field(
        "speed", "m/s", 20e-6, 0.0, 2.6e-3, lo_open=True, display="mm/s",
        help="plate speed of the ramp and of the corrections"))
    rate: float = rate_field()
    period: float = param(Field(
        "period", "s", 0.5, 0.01, 60.0, help="feedback period: force averaged, then corrected"))
    gain: float = param(Field(
        "gain", "", 0.5, 0.0, 1.0, lo_open=True,
        help="fraction of the force error corrected per period (through the Hertz stiffness)"))
    max_step: float = param(Field(
        "max_step", "m", 5e-6, 0.0, 1e-3, lo_open=True, display="um",
        help="largest correction per period"))
    max_depth: float = param(Field(
        "max_depth", "m", 2e-3, 0.0, 20e-3, lo_open=True, display="mm",
        help="give up if the overlap would pass this (at most [limits] max_overlap)"))
    approach: float = param(Field(
        "approach", "m", 0.1e-3, 0.0, 5e-3, display="mm",
        help="start the ramp this far before first touch"))
    tare_time: float = param(Field(
        "tare_time", "s", 1.0, 0.0, 60.0, help="force averaged for a tare before the ramp"))
    retract: float = param(Field(
        "retract", "m", 2e-3, 0.0, 20e-3, display="mm",
        help="back-off from first touch afterwards"))
    first_touch: float | None = first_touch_field()


@dataclass(frozen=True)
class CreepResult(StepResult):
    """The creep: plate position at the start and end of the hold and ``history`` (ten
    means of [t_s, delta_m] over the hold, t from its start); how well the force was held:
    its mean, rms error, the largest error of a feedback period's mean, and whether that
    stayed within ``tolerance_N``."""

    first_touch_m: float
    target_N: float  # noqa: N815 (run.json key: units in the name)
    held_s: float
    samples: int
    start_position_m: float
    end_position_m: float
    creep_m: float
    force_mean_N: float  # noqa: N815
    force_rms_error_N: float  # noqa: N815
    corrections: int
    history: list[list[float]] = field(default_factory=list)
    tolerance_N: float = math.nan  # noqa: N815
    force_max_error_N: float = math.nan  # noqa: N815
    within_tolerance: bool = False


class Creep(StepDefinition[CompressionRig, CreepParams, CreepResult]):
    """Ramp to a force, then hold it by moving the stage under feedback."""

    kind: ClassVar[str] = "creep"
    rig = CompressionRig
    Params, Result = CreepParams, CreepResult
    description: ClassVar[str] = "creep at constant force"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: CreepParams, limits: Limits) -> StepPlan:
        p = params
        ramp = (p.approach + p.max_depth) / p.speed
        checks = []
        if isinstance(limits, CompressionLimits):
            ok = p.force < limits.max_force
            checks.append(PlanCheck("force", ok, f"target {p.force * 1e3:g} mN "
                                    f"{'<' if ok else '>='} force limit "
                                    f"{limits.max_force * 1e3:g} mN"))
        return StepPlan(ramp + p.hold + p.tare_time, p.approach + p.max_depth + 2 * p.retract, [
            f"ramp at {p.speed * 1e6:.2f} um/s until {p.force * 1e3:g} mN (at most "
            f"{p.max_depth * 1e3:g} mm past first touch, {ramp:.0f} s)",
            f"hold {p.force * 1e3:g} mN +- {p.tolerance * 1e3:g} mN for {p.hold:g} s: every "
            f"{p.period:g} s correct {p.gain:g} of the error (at most {p.max_step * 1e6:g} "
            f"um), at {p.rate:g} Hz"], checks, samples=(ramp + p.hold + p.tare_time) * p.rate)

    def preflight(self, params: CreepParams, rig: CompressionRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        p, limits = params, rig.limits
        caps = rig.stage_caps
        why = [stage_speed_error(p.speed, caps), stage_speed_error(limits.fast_speed, caps)]
        if p.force >= limits.max_force:
            why.append(f"force {p.force * 1e3:g} mN at or above the force limit "
                       f"{limits.max_force * 1e3:g} mN ([limits] max_force)")
        if p.max_depth > limits.max_overlap:
            why.append(f"max_depth {p.max_depth * 1e3:g} mm beyond the overlap limit "
                       f"{limits.max_overlap * 1e3:g} mm ([limits] max_overlap)")
        why += touch_problems("creep", p.first_touch, (-p.approach, p.max_depth), rig, earlier)
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: CreepParams) -> CreepResult:
        p, rig = params, ctx.rig
        touch = needed_touch(ctx, p.first_touch, "creep")
        rig.first_touch = touch  # where a safe stop retracts from
        ctx.interlocks = rig.interlocks(overlap=True)
        rec = ForceRecorder(ctx, p.rate, first_touch=touch)
        approach(ctx, rec, touch - p.approach, p.tare_time)
        rig.stage.set_velocity(p.speed, rig.limits.acceleration)
        rig.stage.move_to(touch + p.max_depth, wait=False)
        if rec.until_stopped(watch=(p.force,), stop_above=p.force) is None:
            retract(ctx, rec, touch, p.retract)
            raise GelrigError(f"creep: the force never reached {p.force * 1e3:g} mN "
                              f"within {p.max_depth * 1e3:g} mm past first touch")
        rec.clear()
        held, corrections = _hold(ctx, rec, p)
        cols = rec.columns()
        retract(ctx, rec, touch, p.retract)
        t, z, force = cols["t_s"], cols["position_m"], cols["force_N"]
        block = max(1, round(p.period * p.rate))
        tenths = [(i * t.size // 10, (i + 1) * t.size // 10) for i in range(10)]
        history = [[float(t[a:b].mean() - t[0]), float(z[a:b].mean() - touch)]
                   for a, b in tenths if b > a]
        worst = _worst_period(force, block, p.force)
        return CreepResult(touch, p.force, held, int(t.size), float(z[:block].mean()),
                           float(z[-block:].mean()), float(z[-block:].mean() - z[:block].mean()),
                           float(force.mean()),
                           float(math.sqrt(((force - p.force) ** 2).mean())), corrections,
                           history, p.tolerance, worst, bool(worst <= p.tolerance))


def _worst_period(force: FloatArray, block: int, target: float) -> float:
    """The largest error of the mean force over one feedback period (N)."""
    n = force.size // block
    if n == 0:
        return abs(float(force.mean()) - target) if force.size else math.inf
    means = force[:n * block].reshape(n, block).mean(axis=1)
    if force.size > n * block:
        means = np.append(means, force[n * block:].mean())
    return float(np.abs(means - target).max())


def _hold(ctx: Ctx, rec: ForceRecorder, p: CreepParams) -> tuple[float, int]:
    """Hold the force: read one period, compare its mean with the target, and command a
    correction through the Hertz stiffness dF/d(delta) = 1.5 F / delta. Returns the time
    held and the number of corrections."""
    stage, clock = ctx.rig.stage, ctx.clock
    n = max(1, round(p.period * p.rate))
    start = clock.now()
    end = start + p.hold
    corrections = 0
    report = start
    ctx.control.enter_hold()  # a person may end the hold early; its data is kept
    try:
        while clock.now() < end and not ctx.control.hold_end_requested:
            left = max(1, math.ceil((end - clock.now()) * p.rate))
            data = rec.read(n_max=min(n, left))
            if not data["force_N"].size or stage.is_moving():
                continue
            force = float(data["force_N"].mean())
            delta = float(data["delta_m"][-1])
            stiffness = 1.5 * max(force, 0.1 * p.force) / max(delta, 1e-6)
            step = p.gain * (p.force - force) / stiffness
            step = max(-p.max_step, min(p.max_step, step))
            if delta + step > p.max_depth:
                raise GelrigError(f"creep: holding {p.force * 1e3:g} mN needs "
                                  f"more than max_depth {p.max_depth * 1e3:g} mm")
            stage.move_by(step, wait=False)
            corrections += 1
            now = clock.now()
            if now >= report:
                ctx.progress((now - start) / p.hold, now - start, end - now, "creep",
                             force_N=force, delta_m=delta)
                report = now + p.hold / 200
    finally:
        ctx.control.leave_hold()
    return clock.now() - start, corrections
