"""Ramp to a strain at a strain rate from first touch, hold, record, retract, fit the hold
(paper: 6 % of the diameter at 0.002 /s, hold 3000 s, 100 Hz or 1 kHz)."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from gelrig.instrument.analysis.hold import find_hold
from gelrig.instrument.analysis.hold_analysis import measured_overlap
from gelrig.instrument.analysis.live_fit import (
    LiveFit,
    LiveFitState,
    StopRule,
    correlated_inflation,
    white_noise_check,
)
from gelrig.instrument.analysis.quantiser import find_lattice
from gelrig.instrument.analysis.relaxation import fit_hold, modulus_history, shown_amplitude
from gelrig.instrument.core.errors import GelrigError
from gelrig.instrument.core.fields import Field, Where, param
from gelrig.instrument.core.units import lab_time
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.caps import stage_position_error, stage_speed_error
from gelrig.protocols.context import StepContext
from gelrig.protocols.events import FitUpdate, Note
from gelrig.protocols.rig import CompressionLimits, CompressionRig
from gelrig.protocols.steps.acquire import COLUMNS, ForceRecorder
from gelrig.protocols.steps.base import (
    Limits,
    PlanCheck,
    StepDefinition,
    StepParams,
    StepPlan,
    StepResult,
    brief,
    mm,
)
from gelrig.protocols.steps.compression_search import SearchResult

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RampHoldParams(StepParams):
    """Parameters of a ramp and hold (paper: 6 % of the diameter at 0.002 /s, 3000 s)."""

    diameter: float = param(Field("diameter", "m", None, 0.0, 0.1, lo_open=True,
                                  display="mm", help="sphere diameter; default: the run's "
                                                     "sample's (no paper value stands in)"))
    strain: float = param(Field("strain", "", paper.STRAIN_HOLD, 0.0, 0.3, lo_open=True,
                                help="hold overlap / diameter"))
    strain_rate: float = param(Field("strain_rate", "1/s", paper.STRAIN_RATE, 0.0, 1.0,
                                     lo_open=True, help="ramp speed / diameter"))
    hold: float = param(Field("hold", "s", paper.HOLD, 0.0, 7 * 86400.0,
                              help="hold duration"))
    rate: float = param(Field("rate", "Hz", 100.0, 100.0, 20e3, help="force sample rate"))
    approach: float = param(Field("approach", "m", 0.1e-3, 0.0, 5e-3, display="mm",
                                  help="start the ramp this far before first touch"))
    retract: float = param(Field("retract", "m", 2e-3, 0.0, 20e-3, display="mm",
                                 help="back-off from first touch afterwards"))
    first_touch: float | None = param(Field(
        "first_touch", "m", None, 0.0, 25e-3, optional=True, display="mm",
        help="stage position of first touch; default: from the contact search"))
    tare_time: float = param(Field("tare_time", "s", 1.0, 0.0, 60.0,
                                   help="force averaged for a tare just before the ramp, clear "
                                        "of the sphere"))
    terms: float = param(Field("terms", "", 2, 1, 2, integer=True,
                               help="relaxation terms fitted (1 and up to this)"))
    until: float | None = param(Field(
        "until", "", None, 0.0, 0.5, lo_open=True, optional=True,
        help="adaptive hold: end once every time constant's relative standard error is at "
             "most this (e.g. 0.02) on two refits in a row; hold is then the maximum"))
    until_terms: float = param(Field(
        "until_terms", "", 1, 1, 2, integer=True,
        help="adaptive hold: terms the data must resolve before it may end (at most terms)"))
    min_hold: float = param(Field("min_hold", "s", 0.0, 0.0, 7 * 86400.0,
                                  help="adaptive hold: shortest hold (at most hold)"))

    def validate(self, where: Where) -> None:
        if self.min_hold > self.hold:
            raise where.error("min_hold", self.min_hold,
                              f"at most hold ({self.hold:g} s), the adaptive hold's maximum")
        if self.until_terms > self.terms:
            raise where.error("until_terms", self.until_terms,
                              f"at most terms ({int(self.terms)}), the terms fitted")

    @property
    def stop_rule(self) -> StopRule | None:
        """The adaptive hold's rule, or None for a hold of fixed length (the default)."""
        if self.until is None:
            return None
        return StopRule(self.until, int(self.until_terms), self.min_hold)

    @property
    def depth(self) -> float:
        """Overlap held (m)."""
        return self.strain * self.diameter

    @property
    def speed(self) -> float:
        """Ramp speed (m/s)."""
        return self.strain_rate * self.diameter


@dataclass(frozen=True, repr=False)
class RampHoldResult(StepResult):
    """Where the hold was, how many samples it has, and the relaxation fits (1..terms); the
    first touch refitted on the ramp and the measured overlap the fits used."""

    first_touch_m: float
    depth_m: float
    speed_m_s: float
    samples: int
    fits: list[dict[str, Any]] = field(default_factory=list)
    first_touch_ramp_m: float = float("nan")
    measured_depth_m: float = float("nan")
    #: lab seconds the hold lasted (less than asked when a person ended it early)
    held_s: float | None = None
    #: the live fit's refits during the hold (``LiveFitState.as_dict``), oldest first
    live_fits: list[dict[str, Any]] = field(default_factory=list)
    #: why the hold ended: "planned" (fixed hold), "target" (adaptive, met), "maximum"
    #: (adaptive, not met), "requested" (a person ended it)
    hold_end: str = ""
    #: the ramp refit's standard error (m); 0 when the recorded touch stands in
    first_touch_ramp_se_m: float = float("nan")

    def __repr__(self) -> str:
        """One line: depth, hold, the final fit with standard errors, the refits counted."""
        measured = (f" (measured {mm(self.measured_depth_m)})"
                    if math.isfinite(self.measured_depth_m) else "")
        held = "held ? s" if self.held_s is None else f"held {self.held_s:.4g} s"
        refits = len(self.live_fits)
        return brief("RampHoldResult", f"depth {mm(self.depth_m)}{measured}",
                     f"{held}{f' ({self.hold_end})' if self.hold_end else ''}",
                     fit_brief(self.fits[-1]) if self.fits else "no fits",
                     f"{refits} live refit{'' if refits == 1 else 's'}")


def fit_brief(fit: Mapping[str, Any]) -> str:
    """A hold's fit (``RampHoldResult.fits``) in one line: ``2-term fit G_e 1.2e+04 +- 50
    Pa, G_1 ... Pa, tau_1 ... s``, or why it is not a result."""
    if "error" in fit:
        return f"fit failed: {fit['error']}"
    relax = fit.get("relax") or []
    if not fit.get("resolved", True) or "G_e" not in fit:
        return f"fit not resolved: {fit.get('not_resolved') or 'no term resolved'}"
    se = fit.get("stderr") or {}

    def pm(key: str, value: float, unit: str) -> str:
        err = se.get(key)
        shown = f"{err:.2g}" if isinstance(err, int | float) and math.isfinite(err) else "?"
        return f"{key} {value:.4g} +- {shown} {unit}"

    terms = [pm("G_e", float(fit["G_e"]), "Pa")]
    for i, term in enumerate(relax, start=1):
        g, note = shown_amplitude(fit, i, float(term["G"]))
        err = se.get(f"G_{i}")
        if isinstance(err, int | float) and term["G"]:
            se = {**se, f"G_{i}": err * g / float(term["G"])}
        terms += [pm(f"G_{i}", g, "Pa") + note, pm(f"tau_{i}", float(term["tau"]), "s")]
    asked = fit.get("terms_requested")
    head = f"{len(relax)}-term fit" + (f" (of {asked} asked)" if asked else "")
    return f"{head} {', '.join(terms)}"


class RampHold(StepDefinition[CompressionRig, RampHoldParams, RampHoldResult]):
    """Ramp to a strain at a strain rate from first touch, hold, record, retract, fit."""

    kind: ClassVar[str] = "ramp_hold"
    rig = CompressionRig
    Params = RampHoldParams
    Result = RampHoldResult
    description: ClassVar[str] = "ramp and hold"
    sample_fields: ClassVar[Mapping[str, str]] = {"diameter": "diameter"}
    columns: ClassVar[dict[str, str]] = COLUMNS

    def plan(self, params: RampHoldParams, limits: Limits) -> StepPlan:
        p = params
        depth, speed = p.depth, p.speed
        ramp = (depth + p.approach) / speed
        lines = [
            f"ramp {depth * 1e3:.4f} mm ({p.strain * 100:g} % of "
            f"{p.diameter * 1e3:g} mm) at {speed * 1e6:.2f} um/s "
            f"({p.strain_rate:g} /s): {ramp:.1f} s",
            f"hold {p.hold:g} s at {p.rate:g} Hz "
            f"({int(p.hold * p.rate):,} samples), retract "
            f"{p.retract * 1e3:g} mm, fit 1..{int(p.terms)} relaxation terms",
        ]
        checks = []
        if isinstance(limits, CompressionLimits):
            ok = depth <= limits.max_overlap
            checks.append(PlanCheck("overlap", ok, f"depth {depth * 1e3:.4f} mm "
                                    f"{'<=' if ok else '>'} overlap limit "
                                    f"{limits.max_overlap * 1e3:g} mm"))
        back = 2 * p.retract / (limits.fast_speed if isinstance(limits, CompressionLimits)
                                else 1e-3)
        travel = p.approach + depth + p.retract * 2
        rule = p.stop_rule
        if rule is not None:  # the plan's duration is the longest; say the range
            lines.append(f"adaptive hold: {rule.min_hold:g} s to {p.hold:g} s (ends when "
                         f"{rule.describe()}; else at {p.hold:g} s); step "
                         f"{lab_time(ramp + rule.min_hold + back)} to "
                         f"{lab_time(ramp + p.hold + back)}")
        duration = ramp + p.hold + back
        return StepPlan(duration, travel, lines, checks, samples=duration * p.rate)

    def preflight(self, params: RampHoldParams, rig: CompressionRig,
                  earlier: tuple[type[StepResult], ...]) -> list[str]:
        p, caps = params, rig.stage_caps
        why = [stage_speed_error(p.speed, caps), stage_speed_error(rig.limits.fast_speed, caps)]
        if p.depth > rig.limits.max_overlap:
            why.append(f"depth {p.depth * 1e3:.4f} mm beyond the overlap limit "
                       f"{rig.limits.max_overlap * 1e3:g} mm ([limits] max_overlap)")
        if p.first_touch is not None:
            why += [stage_position_error(p.first_touch + p.depth, caps),
                    stage_position_error(p.first_touch - p.approach, caps)]
        elif not any(issubclass(kind, SearchResult) for kind in earlier):
            why.append("ramp_hold needs first_touch, or a contact search before it")
        return [w for w in why if w is not None]

    def run(self, ctx: StepContext[CompressionRig], params: RampHoldParams) -> RampHoldResult:
        p = params
        rig = ctx.rig
        stage, limits = rig.stage, rig.limits
        touch = p.first_touch
        if touch is None:
            found = ctx.earlier(SearchResult)
            if found is None:
                raise GelrigError("ramp_hold needs first_touch, or a contact search before it")
            touch = found.first_touch_m
        rig.first_touch = touch  # where a safe stop retracts from
        depth, speed = p.depth, p.speed
        ctx.interlocks = rig.interlocks(overlap=True)
        if not stage.status().homed:  # positions mean nothing before homing
            stage.home(wait=True)
        # Nobody watches a rehearsal or a campaign member (ctx.watched False): the hold is
        # counted, not kept, so memory does not grow with its length or rate; a run keeps it
        # for the final fits.
        rec = ForceRecorder(ctx, p.rate, first_touch=touch, keep=ctx.watched)
        chain = getattr(rig.force, "chain", None)
        tally = _Tally(touch, float(getattr(chain, "compliance", 0.0)))
        # a rehearsal keeps a thinned copy of the ramp and hold: the fits a script reads
        thin = _Thinned(((depth + p.approach) / speed + p.hold) * p.rate) \
            if ctx.rehearsal and not ctx.watched else None
        rec.start()
        stage.set_velocity(limits.fast_speed, limits.acceleration)
        stage.move_to(touch - p.approach, wait=False)
        rec.until_stopped()
        if p.tare_time > 0:  # clear of the sphere: zero the force here
            rec.tare(p.tare_time)
        rec.clear()
        t_start = ctx.clock.now()
        stage.set_velocity(speed, limits.acceleration)
        stage.move_to(touch + depth, wait=False)
        ramp_time = (depth + p.approach) / speed
        while stage.is_moving():
            block = rec.read()
            if not ctx.watched:
                tally.add(block, hold=False)
            if thin is not None:
                thin.add(block)
            elapsed = ctx.clock.now() - t_start
            ctx.progress(elapsed / (ramp_time + p.hold), elapsed,
                         ramp_time + p.hold - elapsed, "ramp")
        live = _LiveHold(ctx, p)

        def hold_block(data: dict[str, FloatArray]) -> bool:
            if not ctx.watched:
                tally.add(data, hold=True)
            if thin is not None:
                thin.add(data)
            return live.block(data)

        held = rec.dwell(p.hold, progress=True, label="hold", endable=True,
                         after_block=hold_block)
        end = live.end(held)
        if end == "target":
            log.info("adaptive hold ended after %.1f s of at most %g s: %s met", held, p.hold,
                     live.rule.describe() if live.rule else "")
        elif held < p.hold - 1.0 / p.rate:
            log.warning("hold ended early on request after %.1f s of %g s; its data is kept",
                        held, p.hold)
        cols = rec.columns()
        stage.set_velocity(limits.fast_speed, limits.acceleration)
        stage.move_to(max(touch - p.retract, 0.0), wait=False)
        rec.keep = False
        rec.until_stopped()
        history = [s.as_dict() for s in live.fit.history]
        if thin is not None:  # a rehearsal: the same fits, from every k-th sample of the twin
            try:
                measured, fits = _fits(thin.columns(), tally.compliance, p)
            except (GelrigError, ValueError) as exc:  # too short a record to find the hold
                return RampHoldResult(touch, depth, speed, tally.samples,
                                      [{"error": str(exc), "rehearsal": thin.note}],
                                      math.nan, tally.held(), held, history, end)
            return RampHoldResult(touch, depth, speed, tally.samples,
                                  [{**fit, "rehearsal": thin.note} for fit in fits],
                                  measured.first_touch, measured.held, held, history, end,
                                  measured.stderr)
        if not ctx.watched:  # counted only: no ramp refit, no fits (the analysis makes them)
            return RampHoldResult(touch, depth, speed, tally.samples, [], math.nan,
                                  tally.held(), held, history, end)
        measured, fits = _fits(cols, tally.compliance, p)
        return RampHoldResult(touch, depth, speed, int(cols["t_s"].size), fits,
                              measured.first_touch, measured.held, held, history, end,
                              measured.stderr)


def _fits(cols: dict[str, FloatArray], compliance: float, p: RampHoldParams
          ) -> tuple[Any, list[dict[str, Any]]]:
    """The measured overlap and the relaxation fits (1..terms) of a ramp-and-hold record.

    The fit uses the measured overlap: first touch refitted on this ramp, less the load
    cell's deflection (docs/decisions/0160)."""
    measured, overlap = measured_overlap(
        cols["position_m"], cols["force_N"], cols["delta_m"],
        find_hold(delta=cols["delta_m"]).start, compliance,
        trusted=cols["position_flag"] == 0)  # flagged positions stay out of the refit
    fits: list[dict[str, Any]] = []
    for terms in range(1, int(p.terms) + 1):
        try:
            fit = fit_hold(cols["t_s"], cols["force_N"], p.diameter / 2, overlap,
                           terms=terms, delta=cols["delta_m"],
                           overlap_stderr=measured.stderr)
            # run.json says whether the fit it holds is a result (ADR 0261)
            fits.append({**fit.as_dict(), "resolved": fit.resolved.is_resolved})
        except (GelrigError, ValueError) as exc:  # a hold ended early may be too short
            fits.append({"error": str(exc)})
    return measured, fits


#: Most samples a rehearsal keeps of one ramp and hold for its fits (every k-th one): about
#: 160 kB whatever the hold's length or rate.
THIN_POINTS = 4_000
#: The columns the fits read.
_FITTED = ("t_s", "position_m", "delta_m", "force_N", "position_flag")


class _Thinned:
    """Every ``every``-th sample of a ramp and hold (at most about :data:`THIN_POINTS`), in
    constant memory: what a rehearsal fits, so that a script reading ``fits`` rehearses with
    values of the same fields and nearly the same numbers as the run's."""

    def __init__(self, expected: float, most: int = THIN_POINTS):
        self.every = max(1, math.ceil(expected / most))
        self._phase = 0  # samples seen so far, modulo ``every``
        self.kept: dict[str, list[FloatArray]] = {}

    @property
    def note(self) -> str:
        """What a rehearsed fit is: said in the fit's ``rehearsal`` field."""
        return f"fitted on the twin's record, every {self.every}th sample"

    def add(self, data: dict[str, FloatArray]) -> None:
        n = int(data["t_s"].size)
        if not n:
            return
        first = -self._phase % self.every
        for key in _FITTED:  # copies: a view would keep the whole block alive
            self.kept.setdefault(key, []).append(np.array(data[key][first::self.every]))
        self._phase = (self._phase + n) % self.every

    def columns(self) -> dict[str, FloatArray]:
        return {k: np.concatenate(v) for k, v in self.kept.items()}


class _Tally:
    """What a ramp and hold needs of its samples when they are not kept: how many the step
    records from the ramp on, and the mean overlap over the hold (plate position less first
    touch, less the load cell's deflection) -- in constant memory."""

    def __init__(self, touch: float, compliance: float):
        self.touch = touch
        self.compliance = compliance
        self.samples = 0
        self._held_sum = 0.0
        self._held_n = 0

    def add(self, data: dict[str, FloatArray], hold: bool) -> None:
        n = int(data["t_s"].size)
        self.samples += n
        if hold and n:
            overlap = data["position_m"] - self.compliance * data["force_N"] - self.touch
            finite = overlap[np.isfinite(overlap)]
            self._held_sum += float(finite.sum())
            self._held_n += int(finite.size)

    def held(self) -> float:
        """Mean overlap over the hold (m), against the recorded first touch; NaN if none."""
        return self._held_sum / self._held_n if self._held_n else math.nan


def _inflation(chain: object, p: RampHoldParams) -> float:
    """The live fit's error factor for the load cell's correlated noise as confirmed at
    bring-up (``[force.chain] noise_correlated``, ``noise_tau``; 1 without them)."""
    corr, tau = getattr(chain, "noise_correlated", None), getattr(chain, "noise_tau", None)
    if not isinstance(corr, int | float) or not isinstance(tau, int | float):
        return 1.0
    white = getattr(chain, "noise", None)
    return correlated_inflation(float(white) if isinstance(white, int | float) else 0.0,
                                float(corr), float(tau), p.rate, p.hold)


class _LiveHold:
    """The live fit of one hold: turns each block into G(t), refits when due, publishes a
    :class:`FitUpdate`, and (adaptive hold) says when the rule is met."""

    def __init__(self, ctx: StepContext[CompressionRig], p: RampHoldParams):
        self.ctx = ctx
        self.p = p
        self.rule = p.stop_rule
        # the force noise measured at bring-up ([force.chain] noise), if any: what the live
        # fit's white-noise assumption is checked against (issue 30), once per hold; its
        # correlated part widens the live fit's errors (and so lengthens an adaptive hold)
        chain = getattr(ctx.rig.force, "chain", None)
        white = getattr(chain, "noise", None)
        self.white = float(white) if isinstance(white, int | float) else None
        self.fit = LiveFit(int(p.terms), p.hold, p.rate, inflation=_inflation(chain, p))
        self.t0: float | None = None
        self.met = False
        self.checked = False
        self._overlap = math.nan
        self._forces: FloatArray = np.empty(0)  # the latest, for the quantiser's step

    def block(self, data: dict[str, FloatArray]) -> bool:
        """Take one block of the hold; True once the adaptive hold may end."""
        t = data["t_s"]
        if not t.size:
            return False
        if self.rule is None and not self.ctx.watched:  # a rehearsal of a fixed hold: the
            return False  # live fit only informs the display, and nobody looks
        if self.t0 is None:
            self.t0 = float(t[0])
        delta = data["delta_m"]
        ok = delta > 0
        if ok.any():
            g = modulus_history(data["force_N"][ok], delta[ok], self.p.diameter / 2)
            self.fit.add(t[ok] - self.t0, g)
            self._overlap = float(np.mean(delta[ok]))
            if self.white is not None and not self.checked:
                self._forces = np.concatenate((self._forces, data["force_N"]))[-4000:]
        elapsed = float(t[-1]) - self.t0 + 1.0 / self.p.rate
        if not self.fit.due(elapsed):
            return False
        try:
            state = self.fit.refit(elapsed)
        except Exception as exc:  # a failed refit must not end the hold: the next one retries
            log.debug("live refit at %.1f s failed: %s: %s", elapsed, type(exc).__name__, exc)
            return False
        if state is None:
            return False
        self._check_white(state)
        self.met = self.rule is not None and self.rule.done(self.fit.history)
        met_now = self.rule.met(state) if self.rule is not None else False
        self.ctx.bus.publish(FitUpdate(self.ctx.clock.now(), self.ctx.index, state, met_now,
                                       self.met))
        return self.met

    def _check_white(self, state: LiveFitState) -> None:
        """Once the fit has half the planned hold: its residuals against the rig's measured
        white noise with the quantiser's q^2/12 added back (bring-up removed it; the fit sees
        the codes), converted to G at the current overlap; a Note if they exceed it."""
        if self.white is None or self.checked or state.elapsed < 0.5 * self.p.hold \
                or not self._overlap > 0:
            return
        self.checked = True
        lattice = find_lattice(self._forces)
        step = lattice.step if lattice is not None else 0.0
        white = math.sqrt(self.white ** 2 + step ** 2 / 12.0)
        per_newton = float(modulus_history(1.0, self._overlap, self.p.diameter / 2))
        problem = white_noise_check(state.noise, white * per_newton)
        if problem:
            log.warning("%s", problem)
            self.ctx.bus.publish(Note(self.ctx.clock.now(), problem))

    def end(self, held: float) -> str:
        """Why the hold ended."""
        if self.met:
            return "target"
        if held < self.p.hold - 1.0 / self.p.rate:
            return "requested"
        return "maximum" if self.rule is not None else "planned"
