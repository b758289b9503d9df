"""Turn a run directory into the paper's figures and numbers: ``analyze_run(run_dir, out_dir)``.

A composition root like the CLI (it reads the stored rig and protocol tables through their
parsers). It checks the run against its protocol, hands each complete step's columns to the
pure analysis of ``instrument/``, names whatever is missing, and writes ``report.html`` with
PNG figures and CSV tables through the report layer:

- compression (``ramp_hold`` steps): :mod:`gelrig.instrument.analysis.hold_analysis` (G(t) over the
hold, 1-
  and 2-term Prony fits with uncertainties, residuals), shown by
  :mod:`gelrig.instrument.reports.hold`;
- shear (``speed_ladder`` steps): :mod:`gelrig.instrument.analysis.ladder_analysis` (per-pass l_c,
l_g, F_h
  peak/trough, zero-crossing offset and mu, and the ladder-wide model fit), shown by
  :mod:`gelrig.instrument.reports.ladder`.

What stays here is what needs the run directory: which steps were planned and recorded,
their parameters and results, and where the model fit's start geometry comes from.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.instrument.analysis.found_holds import FoundHold, holds_of
from gelrig.instrument.analysis.hold_analysis import HoldAnalysis, NoHold, analyse_hold
from gelrig.instrument.analysis.ladder_analysis import (
    LadderModel,
    LadderStep,
    analyse_ladder_step,
    fit_ladder_model,
)
from gelrig.instrument.analysis.model_fit import FitSetup, ModelFit
from gelrig.instrument.analysis.relaxation import RelaxationFit
from gelrig.instrument.analysis.shear_analysis import LadderAnalysis, with_chords
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.store import RunDirectory, check_path, read_step
from gelrig.instrument.physics import paper
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.reports.any_run import hold_line, step_section
from gelrig.instrument.reports.document import Section, write_report
from gelrig.instrument.reports.hold import hold_problems, hold_section, hold_summary
from gelrig.instrument.reports.ladder import (
    joint_fit_section,
    joint_fit_summary,
    ladder_section,
    ladder_summary,
)
from gelrig.protocols.sample import Sample, parse_sample

log = logging.getLogger(__name__)

#: The paper's step kinds: a run of only these gets the paper's report; a run with any other
#: kind gets every step's columns drawn and its holds found (docs/decisions/0360).
PAPER_KINDS = frozenset({"compression_contact_search", "ramp_hold", "shear_contact_search",
                         "speed_ladder"})


@dataclass(frozen=True)
class StepData:
    """A recorded step: its index, kind, name, status, parameters, results and columns."""

    index: int
    kind: str
    name: str
    status: str
    params: dict[str, Any]
    results: dict[str, Any]
    columns: dict[str, FloatArray]


@dataclass
class AnalysisResult:
    """What ``analyze_run`` produced: the report's path, the stdout summary, the problems."""

    run_dir: Path
    out_dir: Path
    report_path: Path
    summary: str
    problems: list[str]
    holds: dict[int, HoldAnalysis] = field(default_factory=dict)
    hold_fits: dict[int, list[RelaxationFit]] = field(default_factory=dict)
    ladders: dict[int, LadderAnalysis] = field(default_factory=dict)
    model_fits: dict[int, ModelFit] = field(default_factory=dict)
    #: the holds found in steps of other kinds (relaxation or creep), by step index
    found: dict[int, list[FoundHold]] = field(default_factory=dict)
    #: the model fitted to the passes of every ladder step together (two or more)
    joint_fit: ModelFit | None = None
    #: the compression sphere's diameter (m) the holds' strains are taken against
    diameter: float = math.nan
    #: per step index: (name, kind)
    step_names: dict[int, tuple[str, str]] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        """True when nothing was missing or skipped."""
        return not self.problems


@dataclass
class _Context:
    run: RunDirectory
    out: Path
    meta: dict[str, Any]
    problems: list[str]
    sections: list[Section]
    summary: list[str]
    setup: FitSetup
    fit_model: bool
    ladder_steps: dict[int, LadderStep] = field(default_factory=dict)


# -- reading the run -------------------------------------------------------------------------

def _planned_steps(meta: Mapping[str, Any], problems: list[str]) -> list[tuple[str, str, dict]]:
    """(kind, name, params) of every step the stored protocol planned."""
    from gelrig.protocols.spec import parse_protocol

    table = meta.get("protocol")
    if not isinstance(table, dict):
        problems.append("run.json holds no protocol: analysing the recorded steps as found")
        return []
    head = table.get("protocol")
    if isinstance(head, dict) and "script" in head:  # a script's steps are what it recorded
        return [(str(s.get("kind", "?")), str(s.get("name", "?")), dict(s.get("params") or {}))
                for s in sorted(meta.get("steps", []), key=lambda s: int(s["index"]))]
    try:
        spec = parse_protocol(table, "run.json protocol")
    except ConfigError as exc:
        problems.append(f"the stored protocol is not valid ({exc}); using the recorded steps")
        return []
    return [(s.kind, s.name, s.params.to_table()) for s in spec.steps]


def _arm(meta: Mapping[str, Any], problems: list[str]) -> float:
    from gelrig.protocols.rigfile import ShearRigSpec, parse_rig

    try:
        rig = parse_rig(meta["rig"], "run.json rig")
        if not isinstance(rig, ShearRigSpec):
            raise ConfigError("rig.kind", rig.kind, "a shear rig has the rheometer arm")
        return float(rig.rheometer.config.arm)
    except (KeyError, TypeError, ConfigError) as exc:
        problems.append(f"no rheometer arm in the stored rig ({exc}); using the paper's "
                        f"{paper.ARM * 1e3:g} mm")
        return paper.ARM


def load_steps(run: RunDirectory, meta: Mapping[str, Any], problems: list[str]) -> list[StepData]:
    """Every readable step, in order; missing, unfinished or unreadable ones go to problems."""
    planned = _planned_steps(meta, problems)
    recorded = {int(s["index"]): s for s in meta.get("steps", [])}
    for s in meta.get("interrupted_steps", []):
        problems.append(f"step {s['index']} ({s['name']}): an interrupted attempt is kept in "
                        f"{s['file']}; the resumed attempt is analysed")
    indices = sorted(set(recorded) | set(range(len(planned))))
    out = []
    for i in indices:
        kind, name, params = planned[i] if i < len(planned) else ("?", f"step {i}", {})
        rec = recorded.get(i)
        if rec is None:
            problems.append(f"step {i} ({name}, {kind}) was never recorded: the run stopped "
                            "before it")
            continue
        kind, name = rec.get("kind", kind), rec.get("name", name)
        status = str(rec.get("status", "?"))
        path = run.step_file(rec)  # crafted paths, damaged files: ConfigError, one line
        if not path.exists() and not path.is_symlink():
            problems.append(f"step {i} ({name}): data file {rec.get('file')} is missing")
            continue
        columns = read_step(path)
        n = len(next(iter(columns.values()))) if columns else 0
        if status != "completed":
            problems.append(f"step {i} ({name}) is {status}, not completed: analysing the "
                            f"{n} samples recorded")
        out.append(StepData(i, kind, name, status, params, dict(rec.get("results") or {}),
                            columns))
    return out


# -- compression -----------------------------------------------------------------------------

def _compliance(meta: Mapping[str, Any], problems: list[str]) -> float:
    """The load cell's compliance (m/N) from the stored rig's ``[force.chain]``; 0 without."""
    from gelrig.protocols.rigfile import CompressionRigSpec, parse_rig

    try:
        rig = parse_rig(meta["rig"], "run.json rig")
    except (KeyError, TypeError, ConfigError) as exc:
        problems.append(f"no load-cell chain in the stored rig ({exc}); compliance taken as 0")
        return 0.0
    return float(rig.force.chain.compliance) if isinstance(rig, CompressionRigSpec) else 0.0


def _radii(meta: dict[str, Any], r1: float | None, r2: float | None) -> tuple[float, float]:
    """The shear spheres' radii (m): given, else the run's sample (run.json ``sample``, or the
    protocol file's ``[sample]``), else the paper's, logged as a warning (a run recorded
    before samples were inputs)."""
    table = meta.get("protocol")
    found = [meta.get("sample"), table.get("sample") if isinstance(table, dict) else None]
    table_found: dict[str, Any] = next((t for t in found if isinstance(t, dict)), {})
    try:  # SI numbers (run.json) or unit strings (a protocol file's [sample])
        sample: Sample | None = parse_sample(table_found, "run.json sample")
    except ConfigError as exc:
        log.warning("the run's sample is not readable (%s)", exc)
        sample = None
    out = []
    for key, given, default in (("r1", r1, paper.R1_SHEAR), ("r2", r2, paper.R2_SHEAR)):
        recorded = sample.size(key) if sample is not None else None
        if given is not None:
            out.append(float(given))
        elif recorded is not None:
            out.append(recorded)
        else:
            log.warning("%s not given and not in run.json's sample: the paper's %g mm used "
                        "(--%s to give it)", key, default * 1e3, key)
            out.append(default)
    return out[0], out[1]


def _search_spread(steps: list[StepData], hold: StepData) -> float:
    """The spread (m) of the last compression contact search's approaches before ``hold``:
    the uncertainty of its first touch when the ramp cannot refit it (0 without)."""
    spread = 0.0
    for s in steps:
        if s.kind == "compression_contact_search" and s.index < hold.index:
            value = s.results.get("first_touch_spread_m")
            spread = float(value) if isinstance(value, int | float) else 0.0
    return spread if math.isfinite(spread) else 0.0


def _hold(ctx: _Context, step: StepData, search_spread: float = 0.0) -> HoldAnalysis | None:
    """Analyse a ramp_hold step and add its section; None when there is no fit to show.
    ``search_spread`` (m): the contact search's, for the overlap warning."""
    cols = step.columns
    diameter = float(step.params.get("diameter", paper.DIAMETER_COMPRESSION))
    depth = step.results.get("depth_m")
    if depth is None:
        depth = float(step.params.get("strain", paper.STRAIN_HOLD)) * diameter
    where = f"step {step.index} ({step.name})"
    if not {"t_s", "force_N", "delta_m"} <= set(cols):
        ctx.problems.append(f"{where}: no hold data to fit")
        return None
    try:
        hold = analyse_hold(cols["t_s"], cols["force_N"], cols["delta_m"], diameter / 2,
                            float(depth), float(step.params.get("hold", math.nan)),
                            position=cols.get("position_m"),
                            compliance=_compliance(ctx.meta, ctx.problems))
    except NoHold as exc:
        ctx.problems.append(f"{where}: {exc}")
        return None
    ctx.problems.extend(hold_problems(hold, step.index, step.name))
    if not hold.fits:
        return None
    ctx.sections.append(hold_section(hold, step.index, step.name, ctx.out, step.results,
                                     step.params, search_spread))
    ctx.summary.extend(hold_summary(hold, step.index, step.name, step.results, step.params,
                                    search_spread))
    return hold


# -- shear -----------------------------------------------------------------------------------

def _search_geometry(steps: list[StepData], ladder: StepData) -> tuple[float, float, str]:
    """Touch gap (m) and lower-sphere angle (rad) for the fit's start, and where from."""
    touch = float(ladder.params.get("touch_gap") or math.nan)  # None: from the search
    angle = float(ladder.params.get("centre_angle") or math.nan)
    source = "the ladder's parameters"
    for s in steps:
        if s.kind == "shear_contact_search" and s.index < ladder.index:
            if not math.isfinite(touch):
                touch, source = float(s.results.get("touch_gap_m", math.nan)), "the contact search"
            if not math.isfinite(angle):
                angle = float(s.results.get("lower_sphere_angle_rad", math.nan))
    if not (math.isfinite(touch) and math.isfinite(angle)):
        touch = float(ladder.results.get("touch_gap_m", touch))
        angle = float(ladder.results.get("centre_angle_rad", angle))
    return touch, angle, source


def _ladder(ctx: _Context, steps: list[StepData], step: StepData
            ) -> tuple[LadderAnalysis, ModelFit | None] | None:
    """Analyse a speed_ladder step (and fit the model) and add its section."""
    travel = step.params.get("travel")
    try:
        ladder = analyse_ladder_step(step.columns, ctx.setup.arm,
                                     None if travel is None else float(travel),
                                     s=ctx.setup.s)
    except ConfigError as exc:
        ctx.problems.append(f"step {step.index} ({step.name}): {exc}")
        return None
    analysis = ladder.analysis
    ctx.problems.extend(f"step {step.index}: {p}" for p in analysis.problems)
    if not analysis.results:
        ctx.problems.append(f"step {step.index} ({step.name}): no complete pass to analyse")
        return None
    ctx.ladder_steps[step.index] = ladder
    model = _model_fit(ctx, steps, step, ladder) if ctx.fit_model else None
    fit = model.fit if model else None
    levels = with_chords(ladder.levels(fit, ctx.setup.s), ctx.setup.r1, ctx.setup.r2)
    search = next((s.results for s in steps if s.kind == "shear_contact_search"
                   and s.index < step.index), None)
    ctx.sections.append(ladder_section(ladder, levels, model, step.index, step.name,
                                       ctx.setup, ctx.out, search))
    ctx.summary.extend(ladder_summary(ladder, levels, fit, step.index, step.name, ctx.setup,
                                      search))
    return analysis, fit


def _history(steps: list[StepData], step: StepData, problems: list[str] | None = None,
             offsets: Mapping[int, int] | None = None) -> list[dict[str, FloatArray]]:
    """The shear steps up to and including ``step``: the motion the contact has seen. Only
    ``step``'s passes keep their labels (they are the ones fitted). A step recorded after a
    resume on a clock that started again at 0 (runs before resumes continued the run's time
    base) is moved on to start after the step before it, and the problems say so: the model
    integrates the motion in time order. With ``offsets`` (step index -> pass offset), those
    steps keep their passes labelled, renumbered by their offset (a joint fit)."""
    out: list[dict[str, FloatArray]] = []
    end = -math.inf
    for s in steps:
        if s.index > step.index or s.kind not in ("shear_contact_search", "speed_ladder"):
            continue
        if not {"t_s", "angle_rad", "gap_m", "torque_Nm", "normal_force_N", "pass",
                "direction"} <= set(s.columns):
            continue
        columns = dict(s.columns)
        t = columns["t_s"]
        if t.size and t[0] <= end:
            shift = end - float(t[0]) + 1.0
            columns["t_s"] = t + shift
            if problems is not None:
                problems.append(f"step {s.index} ({s.name}): its times start before the step "
                                f"before it ended (a resume that restarted the clock); moved "
                                f"on by {shift:.1f} s for the model fit")
        if offsets is not None and s.index in offsets:
            labels = np.asarray(columns["pass"], dtype=float)
            columns["pass"] = np.where(labels >= 0, labels + offsets[s.index], -1.0)
        elif s.index != step.index or offsets is not None:
            columns["pass"] = np.full(t.size, -1.0)
        if t.size:
            end = float(columns["t_s"][-1])
        out.append(columns)
    return out


def _model_fit(ctx: _Context, steps: list[StepData], step: StepData,
               ladder: LadderStep) -> LadderModel | None:
    """The ladder-wide model fit, or None (with the reason in the problems)."""
    touch, angle, source = _search_geometry(steps, step)
    if not (math.isfinite(touch) and math.isfinite(angle)):
        ctx.problems.append(f"step {step.index}: model fit skipped: no touch gap or lower-sphere "
                            "angle (no contact search result and none in the ladder's parameters)")
        return None
    try:
        model = fit_ladder_model(ladder, _history(steps, step, ctx.problems), ctx.setup, touch,
                                 angle)
    except (ConfigError, ValueError, np.linalg.LinAlgError) as exc:
        ctx.problems.append(f"step {step.index}: model fit failed ({exc})")
        return None
    model.fit.extra["start_from"] = source
    return model


def _joint_fit(ctx: _Context, steps: list[StepData]) -> LadderModel | None:
    """The model fitted to the passes of every analysed ladder step at once (a ladder split
    over steps, one per overlap): each step's passes renumbered after the ones before, the
    motion of every shear step in time order, the start geometry from the first ladder's
    contact search. None (with the reason in the problems) when it cannot be made."""
    order = sorted(ctx.ladder_steps)
    first = next(s for s in steps if s.index == order[0])
    touch, angle, source = _search_geometry(steps, first)
    if not (math.isfinite(touch) and math.isfinite(angle)):
        ctx.problems.append("joint model fit skipped: no touch gap or lower-sphere angle")
        return None
    offsets, next_offset = {}, 0
    for index in order:
        offsets[index] = next_offset
        next_offset += 1 + max((r.index for r in ctx.ladder_steps[index].analysis.results),
                               default=-1)
    last = next(s for s in steps if s.index == order[-1])
    history = _history(steps, last, offsets=offsets)
    results = [dataclasses.replace(r, index=r.index + offsets[i])
               for i in order for r in ctx.ladder_steps[i].analysis.results]
    union = LadderStep(LadderAnalysis(results, []), [], {})
    try:
        model = fit_ladder_model(union, history, ctx.setup, touch, angle)
    except (ConfigError, ValueError, np.linalg.LinAlgError) as exc:
        ctx.problems.append(f"joint model fit failed ({exc})")
        return None
    model.fit.extra["start_from"] = source
    model.fit.extra["steps"] = order
    return model


def _resolution(meta: Mapping[str, Any]) -> float:
    """The stage's position step (m) from the stored rig (1e-8 m without one)."""
    try:
        return 1e-3 / float(meta["rig"]["stage"]["counts_per_mm"])
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return 1e-8


def _diameter(meta: Mapping[str, Any], steps: list[StepData]) -> float | None:
    """The compression sphere's diameter (m): the run's sample's, else a step's parameter;
    None without either."""
    table = meta.get("protocol")
    for raw in (meta.get("sample"), table.get("sample") if isinstance(table, dict) else None):
        if isinstance(raw, dict):
            try:
                size = parse_sample(raw, "run.json sample").size("diameter")
            except ConfigError:
                size = None
            if size is not None:
                return size
    for s in steps:
        value = s.params.get("diameter")
        if isinstance(value, int | float) and value > 0:
            return float(value)
    return None


def _any_step(ctx: _Context, step: StepData, diameter: float | None) -> list[FoundHold]:
    """A step of any other kind: its columns drawn, its holds found and fitted (against the
    paper's sphere, said in the problems, when the run names none)."""
    holds: list[FoundHold] = []
    missing = diameter is None
    if diameter is None:
        diameter = paper.DIAMETER_COMPRESSION
    if "position_m" in step.columns and "force_N" in step.columns:
        holds = holds_of(step.columns, diameter / 2, _resolution(ctx.meta),
                         _compliance(ctx.meta, ctx.problems))
        if holds and missing and not any(
                "no sphere diameter" in p for p in ctx.problems):
            ctx.problems.append(f"no sphere diameter in the run's sample: the paper's "
                                f"{paper.DIAMETER_COMPRESSION * 1e3:g} mm used for the holds "
                                "found")
    ctx.sections.append(step_section(step.index, step.name, step.kind, step.columns, holds,
                                     diameter, ctx.out))
    n = len(next(iter(step.columns.values())))
    ctx.summary.append(f"Step {step.index} ({step.name}, {step.kind}): {n} samples, "
                       f"{len(step.columns)} columns plotted; {len(holds)} hold(s) found")
    ctx.summary += [f"  {hold_line(h, k, diameter)}" for k, h in enumerate(holds, 1)]
    return holds


def _header(path: Path, kind: str, status: str, problems: list[str]) -> list[str]:
    """The summary's first lines: the run, and up to 8 of its problems."""
    header = [f"gelrig analyze {path}  ({kind} rig, run {status})"]
    if problems:
        header.append(f"INCOMPLETE: {len(problems)} problem(s):")
        header += [f"  - {p}" for p in problems[:8]]
        if len(problems) > 8:
            header.append(f"  ... and {len(problems) - 8} more (see the report)")
    return header


# -- entry point -----------------------------------------------------------------------------

def analyze_run(
    run_dir: str | Path,
    out_dir: str | Path | None = None,
    *,
    r1: float | None = None,
    r2: float | None = None,
    terms: int = 1,
    fit_model: bool = True,
    fit_geometry: bool = True,
    unloading: str = "cutoff",
    anisotropic: bool = False,
) -> AnalysisResult:
    """Analyse every complete part of a run directory and write the report.

    ``out_dir`` defaults to ``RUN_DIR/analysis``. ``r1``, ``r2`` (m) are the shear rig's
    sphere radii (default: the run's sample in run.json, else the paper's, said in the
    problems); ``terms`` is the number of relaxation terms of the
    shear model fit, ``unloading`` its unloading model (``cutoff`` or ``mdr``) and
    ``anisotropic`` whether F_h and F_v get separate G_i (the paper's anisotropy). Raises
    ConfigError when there is nothing at all to analyse (or an option is not allowed).
    """
    run = RunDirectory(run_dir)
    meta = run.read_metadata()
    out = Path(out_dir) if out_dir is not None else run.path / "analysis"
    check_path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", str(out), "is a file, not a folder; name a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError("--out", str(out), f"cannot be created ({exc.strerror})") from None
    problems: list[str] = []
    steps = load_steps(run, meta, problems)
    if any(s.kind == "speed_ladder" for s in steps):
        r1, r2 = _radii(meta, r1, r2)
    r1 = paper.R1_SHEAR if r1 is None else r1
    r2 = paper.R2_SHEAR if r2 is None else r2
    head = (meta.get("protocol") or {}).get("protocol")
    kind = str(head.get("rig", "?")) if isinstance(head, dict) else "?"
    arm = _arm(meta, problems) if any(s.kind == "speed_ladder" for s in steps) else paper.ARM
    ctx = _Context(run, out, meta, problems, [], [],
                   FitSetup(r1, r2, arm, terms=terms, fit_geometry=fit_geometry,
                            unloading=unloading, anisotropic=anisotropic), fit_model)
    result = AnalysisResult(run.path, out, out / "report.html", "", problems)
    recorded = [s for s in steps if s.columns and len(next(iter(s.columns.values())))]
    if not recorded:
        raise ConfigError("run", str(run.path), "holds no recorded data"
                          + (f" ({problems[0]})" if problems else ""))
    diameter = _diameter(meta, steps)
    result.diameter = paper.DIAMETER_COMPRESSION if diameter is None else diameter
    # a run of the paper's kinds only keeps the paper's report (and its cost: campaigns)
    paper_only = all(s.kind in PAPER_KINDS for s in recorded)
    for step in recorded:
        result.step_names[step.index] = (step.name, step.kind)
        if step.kind == "ramp_hold":
            hold = _hold(ctx, step, _search_spread(steps, step))
            if hold is not None:
                result.holds[step.index] = hold
                result.hold_fits[step.index] = list(hold.fits)
        elif step.kind == "speed_ladder":
            done = _ladder(ctx, steps, step)
            if done is not None:
                result.ladders[step.index] = done[0]
                if done[1] is not None:
                    result.model_fits[step.index] = done[1]
        elif not paper_only:
            result.found[step.index] = _any_step(ctx, step, diameter)
    if fit_model and len(ctx.ladder_steps) > 1:
        joint = _joint_fit(ctx, steps)
        if joint is not None:
            result.joint_fit = joint.fit
            ctx.sections.append(joint_fit_section(joint.fit, sorted(ctx.ladder_steps),
                                                  ctx.setup))
            ctx.summary += joint_fit_summary(joint.fit, sorted(ctx.ladder_steps), ctx.setup)
    header = _header(run.path, kind, str(meta.get("status", "?")), problems)
    summary = "\n".join([*header, *ctx.summary])
    page = write_report(out, f"gelrig analysis: {run.path.name}", summary, ctx.sections,
                        problems)
    result.summary = summary + f"\nreport: {page.resolve()}"
    result.report_path = page
    return result

