"""Three step kinds for the compression rig, written as a user would: ``rest``,
``load_unload`` and ``creep``. Import this module from a script (``import compression_steps``)
or name it in a protocol file (``[protocol] step_kinds = ["compression_steps.py"]``); then
``kind = "creep"`` works like a built-in kind.

- ``rest``: the plate clear of the sphere, record the force for a while (the sphere
  recovering, the load cell's baseline). Result: mean, spread and drift of the force.
- ``load_unload``: from just before first touch, ramp into the sphere to a depth at a speed
  and straight back out at the same speed, no hold. Result: the peak force, the overlap at
  which the force is gone on the way out, the energy lost in the cycle.
- ``creep``: ramp until the force reaches a target, then hold that force for a while by
  moving the stage under feedback. Result: where the plate started and ended the hold (the
  creep), and how well the force was held.

Each records the force recorder's columns (``t_s``, ``position_m``, ``delta_m`` = overlap past
first touch, ``force_N``, ``over_range``). Every motion happens in ``run()`` while the
recorder reads the force, so the rig's interlocks see every sample; ``preflight`` refuses a
step before anything moves when its parameters are beyond the rig's caps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import gelrig

Rig = gelrig.CompressionRig
Ctx = gelrig.StepContext[gelrig.CompressionRig]
Limits = gelrig.CompressionLimits | gelrig.ShearLimits
#: what the force recorder records (SI units): the columns of every step here
COLUMNS = gelrig.ForceRecorder.columns_published


def _first_touch_field() -> Any:
    return gelrig.param(gelrig.Field(
        "first_touch", "m", None, 0.0, 25e-3, optional=True, display="mm",
        help="stage position of first touch; default: from the contact search before"))


def _touch_problems(kind: str, first_touch: float | None, span: tuple[float, float], rig: Rig,
                    earlier: tuple[type[gelrig.StepResult], ...]) -> list[str]:
    """Preflight of a step that works relative to first touch: the positions it will command
    (``span``: from ``first_touch + span[0]`` to ``first_touch + span[1]``) within the stage's
    travel, or a contact search before it."""
    if first_touch is None:
        if any(issubclass(r, gelrig.SearchResult) for r in earlier):
            return []
        return [f"{kind} needs first_touch, or a contact search before it"]
    why = [gelrig.stage_position_error(first_touch + d, rig.stage_caps) for d in span]
    return [w for w in why if w]


def _first_touch(ctx: Ctx, given: float | None, kind: str) -> float:
    """First touch from the parameter, else from the latest contact search."""
    if given is not None:
        return given
    found = ctx.earlier(gelrig.SearchResult)
    if found is None:
        raise gelrig.GelrigError(f"{kind} needs first_touch, or a contact search before it")
    return found.first_touch_m


def _approach(ctx: Ctx, rec: gelrig.ForceRecorder, position: float, tare_time: float) -> None:
    """Home if needed, go to ``position`` at the fast speed, tare there, clear the record."""
    rig = ctx.rig
    if not rig.stage.status().homed:
        rig.stage.home(wait=True)
    rec.start()
    rig.stage.set_velocity(rig.limits.fast_speed, rig.limits.acceleration)
    rig.stage.move_to(position, wait=False)
    rec.until_stopped()
    if tare_time > 0:
        rec.tare(tare_time)
    rec.clear()


def _move(ctx: Ctx, rec: gelrig.ForceRecorder, target: float, label: str) -> None:
    """Move the plate to ``target`` at the speed set, reading the force all the way."""
    stage = ctx.rig.stage
    start, t0 = stage.position(), ctx.clock.now()
    stage.move_to(target, wait=False)
    while stage.is_moving():
        z = rec.read()["position_m"]
        if z.size:
            done = abs(float(z[-1]) - start) / max(abs(target - start), 1e-12)
            ctx.progress(done, ctx.clock.now() - t0, 0.0, label)
    rec.until_stopped()


def _retract(ctx: Ctx, rec: gelrig.ForceRecorder, touch: float, retract: float) -> None:
    """Back off to ``retract`` before first touch at the fast speed (no longer kept)."""
    rig = ctx.rig
    rig.stage.set_velocity(rig.limits.fast_speed, rig.limits.acceleration)
    rig.stage.move_to(max(touch - retract, rig.stage_caps.min_position_m), wait=False)
    rec.keep = False
    rec.until_stopped()


# -- rest ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RestParams(gelrig.StepParams):
    """Parameters of a rest: how long, how fast to sample, how far clear of the sphere."""

    duration: float = gelrig.param(gelrig.Field("duration", "s", 300.0, 0.0, 7 * 86400.0,
                                                lo_open=True, help="time at rest"))
    rate: float = gelrig.param(gelrig.Field("rate", "Hz", 100.0, 100.0, 20e3,
                                            help="force sample rate"))
    clear: float = gelrig.param(gelrig.Field(
        "clear", "m", 1e-3, 0.0, 20e-3, display="mm",
        help="back the plate off to at least this far before first touch (if it is known)"))
    first_touch: float | None = _first_touch_field()


@dataclass(frozen=True)
class RestResult(gelrig.StepResult):
    """The force at rest: its mean and standard deviation, and its drift (mean of the last
    tenth minus mean of the first tenth)."""

    duration_s: float
    samples: int
    position_m: float
    force_mean_N: float  # noqa: N815 (run.json key: units in the name)
    force_sd_N: float  # noqa: N815
    force_drift_N: float  # noqa: N815


@gelrig.register_step
class Rest(gelrig.StepDefinition[gelrig.CompressionRig, RestParams, RestResult]):
    """The plate clear of the sphere, record the force for a while."""

    kind = "rest"
    rig = gelrig.CompressionRig
    Params, Result = RestParams, RestResult
    description = "rest, plate clear"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: RestParams, limits: Limits) -> gelrig.StepPlan:
        p = params
        return gelrig.StepPlan(p.duration, p.clear, [
            f"back off to {p.clear * 1e3:g} mm before first touch if closer, then record "
            f"the force for {p.duration:g} s at {p.rate:g} Hz"], samples=p.duration * p.rate)

    def preflight(self, params: RestParams, rig: Rig,
                  earlier: tuple[type[gelrig.StepResult], ...]) -> list[str]:
        why = [gelrig.stage_speed_error(rig.limits.fast_speed, rig.stage_caps)]
        if params.first_touch is not None:
            why.append(gelrig.stage_position_error(max(params.first_touch - params.clear, 0.0),
                                                   rig.stage_caps))
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: RestParams) -> RestResult:
        p, rig = params, ctx.rig
        touch = p.first_touch
        if touch is None:
            found = ctx.earlier(gelrig.SearchResult)
            touch = found.first_touch_m if found is not None else rig.first_touch
        ctx.interlocks = rig.interlocks(overlap=touch is not None)
        if not rig.stage.status().homed:
            rig.stage.home(wait=True)
        rec = gelrig.ForceRecorder(ctx, p.rate, first_touch=math.nan if touch is None
                                   else touch)
        rec.start()
        if touch is not None and rig.stage.position() > touch - p.clear:
            rig.stage.set_velocity(rig.limits.fast_speed, rig.limits.acceleration)
            rig.stage.move_to(max(touch - p.clear, rig.stage_caps.min_position_m), wait=False)
            rec.until_stopped()
        rec.clear()
        held = rec.dwell(p.duration, progress=True, label="rest", endable=True)
        cols = rec.columns()
        force = cols["force_N"]
        tenth = max(1, force.size // 10)
        return RestResult(held, int(force.size), float(cols["position_m"].mean()),
                          float(force.mean()), float(force.std()),
                          float(force[-tenth:].mean() - force[:tenth].mean()))


# -- load_unload ------------------------------------------------------------------------------
@dataclass(frozen=True)
class LoadUnloadParams(gelrig.StepParams):
    """Parameters of one loading-unloading cycle: how deep, how fast, from where."""

    diameter: float = gelrig.param(gelrig.Field(
        "diameter", "m", None, 0.0, 0.1, lo_open=True, display="mm",
        help="sphere diameter; default: the run's sample's (LoadUnload.sample_fields)"))
    strain: float = gelrig.param(gelrig.Field("strain", "", 0.04, 0.0, 0.3, lo_open=True,
                                              help="turn-around overlap / diameter"))
    depth: float | None = gelrig.param(gelrig.Field(
        "depth", "m", None, 0.0, 20e-3, lo_open=True, optional=True, display="mm",
        help="turn-around overlap; default: strain x diameter"))
    speed: float = gelrig.param(gelrig.Field("speed", "m/s", 37.26e-6, 0.0, 2.6e-3,
                                             lo_open=True, display="mm/s",
                                             help="plate speed, in and out"))
    approach: float = gelrig.param(gelrig.Field(
        "approach", "m", 0.1e-3, 0.0, 5e-3, display="mm",
        help="start (and end) this far before first touch"))
    rate: float = gelrig.param(gelrig.Field("rate", "Hz", 100.0, 100.0, 20e3,
                                            help="force sample rate"))
    tare_time: float = gelrig.param(gelrig.Field(
        "tare_time", "s", 1.0, 0.0, 60.0, help="force averaged for a tare before the ramp"))
    zero_force: float = gelrig.param(gelrig.Field(
        "zero_force", "N", 1e-3, 0.0, 0.1, lo_open=True,
        help="force below which the sphere counts as let go on the way out"))
    retract: float = gelrig.param(gelrig.Field(
        "retract", "m", 2e-3, 0.0, 20e-3, display="mm",
        help="back-off from first touch afterwards"))
    first_touch: float | None = _first_touch_field()

    @property
    def turn(self) -> float:
        """Overlap at the turn-around (m)."""
        return self.depth if self.depth is not None else self.strain * self.diameter


@dataclass(frozen=True)
class LoadUnloadResult(gelrig.StepResult):
    """The cycle's peak force (running mean over 1 % of the samples), the overlap where the
    plate turned, where the force was gone on the way out (overlap; NaN if it never fell
    below ``zero_force``), and the energy lost (loading minus unloading work)."""

    first_touch_m: float
    depth_m: float
    speed_m_s: float
    samples: int
    turn_index: int
    peak_force_N: float  # noqa: N815 (run.json key: units in the name)
    turn_delta_m: float
    release_delta_m: float
    hysteresis_J: float  # noqa: N815


@gelrig.register_step
class LoadUnload(gelrig.StepDefinition[gelrig.CompressionRig, LoadUnloadParams,
                                       LoadUnloadResult]):
    """Ramp into the sphere to a depth and straight back out at the same speed."""

    kind = "load_unload"
    rig = gelrig.CompressionRig
    Params, Result = LoadUnloadParams, LoadUnloadResult
    description = "loading-unloading cycle"
    # the diameter is the sample's: taken from the run's sample when the step gives none,
    # refused before anything moves when neither does (no sphere is assumed)
    sample_fields: ClassVar[dict[str, str]] = {"diameter": "diameter"}
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: LoadUnloadParams, limits: Limits) -> gelrig.StepPlan:
        p = params
        span = p.approach + p.turn
        checks = []
        if isinstance(limits, gelrig.CompressionLimits):
            ok = p.turn <= limits.max_overlap
            checks.append(gelrig.PlanCheck("overlap", ok, f"depth {p.turn * 1e3:.4f} mm "
                                           f"{'<=' if ok else '>'} overlap limit "
                                           f"{limits.max_overlap * 1e3:g} mm"))
        return gelrig.StepPlan(2 * span / p.speed + p.tare_time, 2 * span + 2 * p.retract, [
            f"in to {p.turn * 1e3:.4f} mm past first touch and back out at "
            f"{p.speed * 1e6:.2f} um/s: {2 * span / p.speed:.1f} s at {p.rate:g} Hz"], checks,
            samples=(2 * span / p.speed + p.tare_time) * p.rate)

    def preflight(self, params: LoadUnloadParams, rig: Rig,
                  earlier: tuple[type[gelrig.StepResult], ...]) -> list[str]:
        p = params
        caps = rig.stage_caps
        why = [gelrig.stage_speed_error(p.speed, caps),
               gelrig.stage_speed_error(rig.limits.fast_speed, caps)]
        if p.turn > rig.limits.max_overlap:
            why.append(f"depth {p.turn * 1e3:.4f} mm beyond the overlap limit "
                       f"{rig.limits.max_overlap * 1e3:g} mm ([limits] max_overlap)")
        why += _touch_problems("load_unload", p.first_touch, (-p.approach, p.turn), rig,
                               earlier)
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: LoadUnloadParams) -> LoadUnloadResult:
        p, rig = params, ctx.rig
        touch = _first_touch(ctx, p.first_touch, "load_unload")
        rig.first_touch = touch  # where a safe stop retracts from
        ctx.interlocks = rig.interlocks(overlap=True)
        # a block spans at most 2 um of travel (positions are interpolated between polls),
        # 0.1 to 0.5 s: a slow cycle has many samples (blocks shrink near the force limit)
        block = min(0.5, max(0.1, 2e-6 / p.speed))
        rec = gelrig.ForceRecorder(ctx, p.rate, first_touch=touch, block_time=block)
        _approach(ctx, rec, touch - p.approach, p.tare_time)
        rig.stage.set_velocity(p.speed, rig.limits.acceleration)
        _move(ctx, rec, touch + p.turn, "loading")
        turn = int(rec.columns()["t_s"].size)
        _move(ctx, rec, touch - p.approach, "unloading")
        cols = rec.columns()
        _retract(ctx, rec, touch, p.retract)
        force, delta = cols["force_N"], cols["delta_m"]
        # peak: the highest running mean over 1 % of the cycle's samples (noise averaged, the
        # same share of the travel at every speed)
        k = max(1, force.size // 100)
        sums = force.cumsum()
        peak = float(sums[k - 1]) / k if k == force.size else float(
            max(sums[k - 1], (sums[k:] - sums[:-k]).max())) / k
        out = force[turn:] < p.zero_force
        release = float(delta[turn + int(out.argmax())]) if out.any() else math.nan
        work = (force[1:] + force[:-1]) * (delta[1:] - delta[:-1]) / 2
        return LoadUnloadResult(touch, p.turn, p.speed, int(force.size), turn,
                                peak, float(delta.max()), release,
                                float(work.sum()))


# -- creep ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CreepParams(gelrig.StepParams):
    """Parameters of a creep test: the force to hold, for how long, and the feedback."""

    force: float = gelrig.param(gelrig.Field("force", "N", 0.1, 0.0, 100.0, lo_open=True,
                                             help="force held (below [limits] max_force)"))
    hold: float = gelrig.param(gelrig.Field("hold", "s", 600.0, 0.0, 7 * 86400.0,
                                            lo_open=True, help="time the force is held"))
    speed: float = gelrig.param(gelrig.Field(
        "speed", "m/s", 20e-6, 0.0, 2.6e-3, lo_open=True, display="mm/s",
        help="plate speed of the ramp and of the corrections"))
    rate: float = gelrig.param(gelrig.Field("rate", "Hz", 100.0, 100.0, 20e3,
                                            help="force sample rate"))
    period: float = gelrig.param(gelrig.Field(
        "period", "s", 0.5, 0.01, 60.0, help="feedback period: force averaged, then corrected"))
    gain: float = gelrig.param(gelrig.Field(
        "gain", "", 0.5, 0.0, 1.0, lo_open=True,
        help="fraction of the force error corrected per period (through the Hertz stiffness)"))
    max_step: float = gelrig.param(gelrig.Field(
        "max_step", "m", 5e-6, 0.0, 1e-3, lo_open=True, display="um",
        help="largest correction per period"))
    max_depth: float = gelrig.param(gelrig.Field(
        "max_depth", "m", 2e-3, 0.0, 20e-3, lo_open=True, display="mm",
        help="give up if the overlap would pass this (at most [limits] max_overlap)"))
    approach: float = gelrig.param(gelrig.Field(
        "approach", "m", 0.1e-3, 0.0, 5e-3, display="mm",
        help="start the ramp this far before first touch"))
    tare_time: float = gelrig.param(gelrig.Field(
        "tare_time", "s", 1.0, 0.0, 60.0, help="force averaged for a tare before the ramp"))
    retract: float = gelrig.param(gelrig.Field(
        "retract", "m", 2e-3, 0.0, 20e-3, display="mm",
        help="back-off from first touch afterwards"))
    first_touch: float | None = _first_touch_field()


@dataclass(frozen=True)
class CreepResult(gelrig.StepResult):
    """The creep: overlap at the start and end of the hold and ``history`` (ten means of
    [t_s, delta_m] over the hold, t from its start); how well the force was held."""

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


@gelrig.register_step
class Creep(gelrig.StepDefinition[gelrig.CompressionRig, CreepParams, CreepResult]):
    """Ramp to a force, then hold it by moving the stage under feedback."""

    kind = "creep"
    rig = gelrig.CompressionRig
    Params, Result = CreepParams, CreepResult
    description = "creep at constant force"
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: CreepParams, limits: Limits) -> gelrig.StepPlan:
        p = params
        ramp = (p.approach + p.max_depth) / p.speed
        checks = []
        if isinstance(limits, gelrig.CompressionLimits):
            ok = p.force < limits.max_force
            checks.append(gelrig.PlanCheck("force", ok, f"target {p.force * 1e3:g} mN "
                                           f"{'<' if ok else '>='} force limit "
                                           f"{limits.max_force * 1e3:g} mN"))
        return gelrig.StepPlan(ramp + p.hold + p.tare_time, p.approach + p.max_depth
                               + 2 * p.retract, [
            f"ramp at {p.speed * 1e6:.2f} um/s until {p.force * 1e3:g} mN (at most "
            f"{p.max_depth * 1e3:g} mm past first touch, {ramp:.0f} s)",
            f"hold {p.force * 1e3:g} mN for {p.hold:g} s: every {p.period:g} s correct "
            f"{p.gain:g} of the error (at most {p.max_step * 1e6:g} um), at {p.rate:g} Hz"],
            checks, samples=(ramp + p.hold + p.tare_time) * p.rate)

    def preflight(self, params: CreepParams, rig: Rig,
                  earlier: tuple[type[gelrig.StepResult], ...]) -> list[str]:
        p, limits = params, rig.limits
        caps = rig.stage_caps
        why = [gelrig.stage_speed_error(p.speed, caps),
               gelrig.stage_speed_error(limits.fast_speed, caps)]
        if p.force >= limits.max_force:
            why.append(f"force {p.force * 1e3:g} mN at or above the force limit "
                       f"{limits.max_force * 1e3:g} mN ([limits] max_force)")
        if p.max_depth > limits.max_overlap:
            why.append(f"max_depth {p.max_depth * 1e3:g} mm beyond the overlap limit "
                       f"{limits.max_overlap * 1e3:g} mm ([limits] max_overlap)")
        why += _touch_problems("creep", p.first_touch, (-p.approach, p.max_depth), rig,
                               earlier)
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: CreepParams) -> CreepResult:
        p, rig = params, ctx.rig
        touch = _first_touch(ctx, p.first_touch, "creep")
        rig.first_touch = touch  # where a safe stop retracts from
        ctx.interlocks = rig.interlocks(overlap=True)
        rec = gelrig.ForceRecorder(ctx, p.rate, first_touch=touch)
        _approach(ctx, rec, touch - p.approach, p.tare_time)
        rig.stage.set_velocity(p.speed, rig.limits.acceleration)
        rig.stage.move_to(touch + p.max_depth, wait=False)
        if rec.until_stopped(watch=(p.force,), stop_above=p.force) is None:
            _retract(ctx, rec, touch, p.retract)
            raise gelrig.GelrigError(f"creep: the force never reached {p.force * 1e3:g} mN "
                                     f"within {p.max_depth * 1e3:g} mm past first touch")
        rec.clear()
        held, corrections = self._hold(ctx, rec, p, touch)
        cols = rec.columns()
        _retract(ctx, rec, touch, p.retract)
        t, z, force = cols["t_s"], cols["position_m"], cols["force_N"]
        block = max(1, round(p.period * p.rate))
        tenths = [(i * t.size // 10, (i + 1) * t.size // 10) for i in range(10)]
        history = [[float(t[a:b].mean() - t[0]), float(z[a:b].mean() - touch)]
                   for a, b in tenths if b > a]
        return CreepResult(touch, p.force, held, int(t.size), float(z[:block].mean()),
                           float(z[-block:].mean()), float(z[-block:].mean() - z[:block].mean()),
                           float(force.mean()),
                           float(math.sqrt(((force - p.force) ** 2).mean())), corrections,
                           history)

    @staticmethod
    def _hold(ctx: Ctx, rec: gelrig.ForceRecorder, p: CreepParams,
              touch: float) -> tuple[float, int]:
        """Hold the force: read one period, compare its mean with the target, and command a
        correction through the Hertz stiffness dF/d(delta) = 1.5 F / delta. Returns the
        time held and the number of corrections."""
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
                    raise gelrig.GelrigError(f"creep: holding {p.force * 1e3:g} mN needs "
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
