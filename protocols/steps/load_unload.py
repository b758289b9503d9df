"""``load_unload``: from just before first touch, ramp into the sphere and straight back out
at the same speed, no hold, ``cycles`` times. The plate turns at an overlap (``strain`` of the
diameter, or ``depth``) or where the force reaches ``to_force``."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

from gelrig.instrument.core.errors import GelrigError
from gelrig.instrument.core.fields import Field, Where, param
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
    move_recorded,
    needed_touch,
    rate_field,
    retract,
    touch_problems,
)

TURN = "where to turn: strain, depth or to_force"


@dataclass(frozen=True)
class LoadUnloadParams(StepParams):
    """Parameters of loading-unloading cycles: where to turn (one of ``strain``, ``depth``,
    ``to_force``), how fast, how many times, from where."""

    diameter: float = param(Field(
        "diameter", "m", None, 0.0, 0.1, lo_open=True, display="mm",
        help="sphere diameter; default: the run's sample's"))
    strain: float | None = param(Field(
        "strain", "", None, 0.0, 0.3, lo_open=True, optional=True,
        help="turn at this overlap / diameter"))
    depth: float | None = param(Field(
        "depth", "m", None, 0.0, 20e-3, lo_open=True, optional=True, display="mm",
        help="turn at this overlap (with strain: must equal strain x diameter)"))
    to_force: float | None = param(Field(
        "to_force", "N", None, 0.0, 100.0, lo_open=True, optional=True, display="mN",
        help="turn where the force reaches this (below [limits] max_force), instead of an "
             "overlap"))
    max_depth: float = param(Field(
        "max_depth", "m", 2e-3, 0.0, 20e-3, lo_open=True, display="mm",
        help="with to_force: give up if the overlap would pass this"))
    cycles: float = param(Field("cycles", "", 1, 1, 1000, integer=True,
                                help="cycles, one after the other (results per cycle)"))
    speed: float = param(Field("speed", "m/s", 37.26e-6, 0.0, 2.6e-3, lo_open=True,
                               display="mm/s", help="plate speed, in and out"))
    approach: float = param(Field(
        "approach", "m", 0.1e-3, 0.0, 5e-3, display="mm",
        help="start (and end) each cycle this far before first touch"))
    rate: float = rate_field()
    tare_time: float = param(Field(
        "tare_time", "s", 1.0, 0.0, 60.0, help="force averaged for a tare before the ramp"))
    zero_force: float = param(Field(
        "zero_force", "N", 1e-3, 0.0, 0.1, lo_open=True,
        help="force below which the sphere counts as let go on the way out"))
    retract: float = param(Field(
        "retract", "m", 2e-3, 0.0, 20e-3, display="mm",
        help="back-off from first touch afterwards"))
    first_touch: float | None = first_touch_field()

    def validate(self, where: Where) -> None:
        overlap = self.strain is not None or self.depth is not None
        if self.to_force is not None and overlap:
            key = "strain" if self.strain is not None else "depth"
            raise where.error(key, getattr(self, key), "give either to_force or an overlap "
                              "(strain or depth), not both; with to_force, max_depth bounds "
                              "the ramp")
        if self.to_force is None and not overlap:
            raise where.error("to_force", "missing", f"give {TURN}")
        if (self.strain is not None and self.depth is not None and self.diameter is not None
                and not math.isclose(self.depth, self.strain * self.diameter, rel_tol=1e-6)):
            raise where.error("depth", self.depth, f"contradicts strain {self.strain:g} x "
                              f"diameter {self.diameter * 1e3:g} mm = "
                              f"{self.strain * self.diameter * 1e3:.4g} mm; give one of them")

    @property
    def turn(self) -> float | None:
        """Overlap at the turn-around (m); None when the force says where to turn."""
        if self.depth is not None:
            return self.depth
        return None if self.strain is None else self.strain * self.diameter

    @property
    def deepest(self) -> float:
        """The deepest overlap the plate may be sent to (m)."""
        turn = self.turn
        return self.max_depth if turn is None else turn


@dataclass(frozen=True)
class LoadUnloadResult(StepResult):
    """The first cycle's peak force (running mean over 1 % of its samples), the overlap
    where the plate turned, where the force was gone on the way out (overlap; NaN if it never
    fell below ``zero_force``) and the energy lost (loading minus unloading work); ``cycles``
    has the same for every cycle, with the sample indices where each starts, turns and ends
    (``start_index``, ``turn_index``, ``end_index``)."""

    first_touch_m: float
    depth_m: float
    speed_m_s: float
    samples: int
    turn_index: int
    peak_force_N: float  # noqa: N815 (run.json key: units in the name)
    turn_delta_m: float
    release_delta_m: float
    hysteresis_J: float  # noqa: N815
    to_force_N: float = math.nan  # noqa: N815
    cycles: list[dict[str, Any]] = field(default_factory=list)


class LoadUnload(StepDefinition[CompressionRig, LoadUnloadParams, LoadUnloadResult]):
    """Ramp into the sphere and straight back out at the same speed, ``cycles`` times."""

    kind: ClassVar[str] = "load_unload"
    rig = CompressionRig
    Params, Result = LoadUnloadParams, LoadUnloadResult
    description: ClassVar[str] = "loading-unloading cycle"
    # the diameter is the sample's: taken from the run's sample when the step gives none
    sample_fields: ClassVar[dict[str, str]] = {"diameter": "diameter"}
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: LoadUnloadParams, limits: Limits) -> StepPlan:
        p = params
        n = int(p.cycles)
        span = p.approach + p.deepest
        checks = []
        if isinstance(limits, CompressionLimits):
            ok = p.deepest <= limits.max_overlap
            checks.append(PlanCheck("overlap", ok, f"depth {p.deepest * 1e3:.4f} mm "
                                    f"{'<=' if ok else '>'} overlap limit "
                                    f"{limits.max_overlap * 1e3:g} mm"))
            if p.to_force is not None:
                ok = p.to_force < limits.max_force
                checks.append(PlanCheck("force", ok, f"to_force {p.to_force * 1e3:g} mN "
                                        f"{'<' if ok else '>='} force limit "
                                        f"{limits.max_force * 1e3:g} mN"))
        turn = (f"in to {p.turn * 1e3:.4f} mm past first touch" if p.turn is not None else
                f"in until {(p.to_force or 0.0) * 1e3:g} mN (at most {p.max_depth * 1e3:g} mm "
                "past first touch)")
        cycle = 2 * span / p.speed
        times = f"{n} cycles" if n > 1 else "one cycle"
        return StepPlan(n * cycle + p.tare_time, n * 2 * span + 2 * p.retract, [
            f"{turn} and back out at {p.speed * 1e6:.2f} um/s: {times} of at most "
            f"{cycle:.1f} s at {p.rate:g} Hz"], checks,
            samples=(n * cycle + p.tare_time) * p.rate)

    def preflight(self, params: LoadUnloadParams, rig: CompressionRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        p, limits, caps = params, rig.limits, rig.stage_caps
        why = [stage_speed_error(p.speed, caps), stage_speed_error(limits.fast_speed, caps)]
        name = "depth" if p.turn is not None else "max_depth"
        if p.deepest > limits.max_overlap:
            why.append(f"{name} {p.deepest * 1e3:.4f} mm beyond the overlap limit "
                       f"{limits.max_overlap * 1e3:g} mm ([limits] max_overlap)")
        if p.to_force is not None and p.to_force >= limits.max_force:
            why.append(f"to_force {p.to_force * 1e3:g} mN at or above the force limit "
                       f"{limits.max_force * 1e3:g} mN ([limits] max_force)")
        why += touch_problems("load_unload", p.first_touch, (-p.approach, p.deepest), rig,
                              earlier)
        return [w for w in why if w]

    def run(self, ctx: Ctx, params: LoadUnloadParams) -> LoadUnloadResult:
        p, rig = params, ctx.rig
        touch = needed_touch(ctx, p.first_touch, "load_unload")
        rig.first_touch = touch  # where a safe stop retracts from
        ctx.interlocks = rig.interlocks(overlap=True)
        # a block spans at most 2 um of travel (positions are interpolated between polls),
        # 0.1 to 0.5 s: a slow cycle has many samples (blocks shrink near the force limit)
        block = min(0.5, max(0.1, 2e-6 / p.speed))
        rec = ForceRecorder(ctx, p.rate, first_touch=touch, block_time=block)
        approach(ctx, rec, touch - p.approach, p.tare_time)
        rig.stage.set_velocity(p.speed, rig.limits.acceleration)
        marks = []
        n = int(p.cycles)
        for c in range(n):
            label = f"cycle {c + 1} of {n}: " if n > 1 else ""
            start = _kept(rec)
            if p.turn is None:
                if move_recorded(ctx, rec, touch + p.max_depth, f"{label}loading",
                                 stop_above=p.to_force) is None:
                    retract(ctx, rec, touch, p.retract)
                    raise GelrigError(f"load_unload: the force never reached "
                                      f"{(p.to_force or 0) * 1e3:g} mN within "
                                      f"{p.max_depth * 1e3:g} mm past first touch")
            else:
                move_recorded(ctx, rec, touch + p.turn, f"{label}loading")
            turn = _kept(rec)
            move_recorded(ctx, rec, touch - p.approach, f"{label}unloading")
            marks.append((start, turn, _kept(rec)))
        cols = rec.columns()
        retract(ctx, rec, touch, p.retract)
        cycles = [_cycle(cols, a, t, b, p.zero_force) for a, t, b in marks]
        first = cycles[0]
        return LoadUnloadResult(
            touch, math.nan if p.turn is None else p.turn, p.speed, int(cols["t_s"].size),
            first["turn_index"], first["peak_force_N"], first["turn_delta_m"],
            first["release_delta_m"], first["hysteresis_J"],
            math.nan if p.to_force is None else p.to_force, cycles)


def _kept(rec: ForceRecorder) -> int:
    return sum(len(v) for v in rec.kept["t_s"])


def _cycle(cols: dict[str, FloatArray], start: int, turn: int, end: int,
           zero_force: float) -> dict[str, Any]:
    """One cycle's figures from its samples ``start:end`` (turning at ``turn``)."""
    force, delta = cols["force_N"][start:end], cols["delta_m"][start:end]
    k = max(1, force.size // 100)
    # peak: the highest running mean over 1 % of the cycle's samples (noise averaged, the
    # same share of the travel at every speed)
    sums = force.cumsum()
    peak = float(sums[k - 1]) / k if k == force.size else float(
        max(sums[k - 1], (sums[k:] - sums[:-k]).max())) / k
    out = force[turn - start:] < zero_force
    release = float(delta[turn - start + int(out.argmax())]) if out.any() else math.nan
    work = (force[1:] + force[:-1]) * (delta[1:] - delta[:-1]) / 2
    return {"start_index": start, "turn_index": turn, "end_index": end,
            "peak_force_N": peak, "turn_delta_m": float(delta.max()),
            "release_delta_m": release, "hysteresis_J": float(work.sum())}
