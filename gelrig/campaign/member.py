"""One campaign member: the rig twin with the member's hidden truth, its protocol run in
virtual time into a run directory, the run analysed, one flat record back.

Runs on a Dask worker (or in process): it takes a :class:`~gelrig.campaign.spec.MemberSpec`
(plain tables, so a remote worker needs no campaign file) and never raises; a member that
fails returns its record with ``status = "failed"`` and the error in one line.

:func:`member_procedure` resolves a member's procedure once (a protocol file's table, or a
script loaded by path on the worker and called with the member's parameters);
:func:`run_protocol` runs it through the run host, as every front end does.
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
import time
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from gelrig.campaign.spec import SCRIPT_SUFFIXES, MemberSpec
from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.procedure import Procedure

#: z of a two-sided 95 % interval: a hold fit reports standard errors only.
Z95 = 1.959963984540054
#: Fitted parameters compared with the truth, in the order the report shows them.
FITTED = ("G_e", "G_1", "tau_1", "G_2", "tau_2", "mu", "touch_gap", "lower_angle")


def run_protocol(rig: Any, procedure: Procedure, run_dir: Path, rig_spec: Any,
                 meta: dict[str, Any] | None = None) -> tuple[str, str, dict[str, str]]:
    """Run ``procedure`` on the built ``rig`` into a new run directory ``run_dir``; returns
    (final state, reason, :func:`safe_stop_columns`). Nobody watches a member: no live refits
    of a fixed hold. A safe stop not confirmed (a frozen or lost link) is tried again as the
    terminal and the API do (:meth:`RunHost.complete_pending`: every 1 s for up to 60 s,
    recorded in run.json as ``safe_state.completed_later``) before the rig is closed."""
    from gelrig.protocols.host import RunHost, create_run
    from gelrig.protocols.runinfo import run_info

    given = meta or {}
    info = run_info(given.get("operator"), given.get("note"), given.get("tags"))
    run = create_run(procedure, rig_spec, "virtual", run_dir, info)
    with RunHost(rig, procedure, run, watched=False) as host:
        state = host.run()
        host.complete_pending()
    return state.value, host.reason, safe_stop_columns(run.read_metadata())


def safe_stop_columns(meta: dict[str, Any]) -> dict[str, str]:
    """What the member's record says of the safe stop (run.json's ``safe_state``):
    ``safe_stop`` "" (the run completed: none was needed), "verified", "completed later"
    (not confirmed at the end, verified by a retry) or "not confirmed"; ``safe_stop_line``
    the last line verified (the retry's, if one completed it)."""
    safe = meta.get("safe_state")
    if not isinstance(safe, dict):
        return {"safe_stop": "", "safe_stop_line": ""}
    later = safe.get("completed_later")
    if isinstance(later, dict) and later.get("verified"):
        return {"safe_stop": "completed later",
                "safe_stop_line": f"{later.get('line', '')} (after {later.get('after_s')} s, "
                                  f"attempt {later.get('attempts')})"}
    return {"safe_stop": "verified" if safe.get("verified") else "not confirmed",
            "safe_stop_line": str(safe.get("line", ""))}


def member_procedure(member: MemberSpec) -> Procedure:
    """The member's procedure, resolved once: a script (loaded by path on the worker, called
    with the member's parameters) or its protocol file's table (the campaign's grid values
    already set in it)."""
    from gelrig.protocols.resolve import resolve_procedure

    sample = (member.run_meta or {}).get("sample")
    if member.protocol_ref.endswith(SCRIPT_SUFFIXES):
        procedure = resolve_procedure(member.protocol_ref, member.params or None)
    elif member.protocol_table is None:
        raise ConfigError("[campaign] protocol", member.protocol_ref,
                          "a protocol file's table is needed")
    else:
        procedure = resolve_procedure(member.protocol_ref, table=member.protocol_table)
    return procedure if not sample else resolve_procedure(procedure, sample=sample)


@contextmanager
def _run_dir(member: MemberSpec) -> Iterator[Path]:
    """A temporary run directory, or ``member.keep_dir`` (kept) when runs are kept."""
    if member.keep_dir is not None:
        path = Path(member.keep_dir)
        if path.exists():  # an earlier, interrupted attempt of this member
            shutil.rmtree(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        yield path
        return
    with tempfile.TemporaryDirectory(prefix=f"gelrig-member-{member.member_id}-") as tmp:
        yield Path(tmp) / "run"


def truth_columns(rig_spec: Any) -> dict[str, Any]:
    """The member's hidden truth as flat ``truth.*`` columns (SI)."""
    from gelrig.protocols.rigfile import ShearRigSpec
    from gelrig.simulators.mcr501.config import PAPER_MATERIAL
    from gelrig.simulators.usb6001.rig import PLATES

    sim = rig_spec.simulator
    out: dict[str, Any] = {}
    if isinstance(rig_spec, ShearRigSpec):
        material = sim.material or PAPER_MATERIAL
        out.update({"truth.mu": sim.mu, "truth.touch_gap": sim.touch_gap,
                    "truth.torque_noise": sim.torque_noise,
                    "truth.normal_force_noise": sim.normal_force_noise,
                    "truth.lower_angle": sim.lower_angle, "truth.r1": sim.r1,
                    "truth.r2": sim.r2, "truth.unloading": sim.unloading})
    else:
        material = sim.material or PLATES
        out.update({"truth.noise": sim.noise, "truth.sphere_diameter": sim.sphere_diameter,
                    "truth.first_touch": sim.first_touch})
    out["truth.G_e"] = material.g_e
    for k, term in enumerate(material.relax, start=1):
        out[f"truth.G_{k}"], out[f"truth.tau_{k}"] = term.g, term.tau
    return out


def _estimate(out: dict[str, Any], name: str, value: float, se: float, lo: float,
              hi: float) -> None:
    out[f"fit.{name}"], out[f"se.{name}"] = value, se
    out[f"lo.{name}"], out[f"hi.{name}"] = lo, hi


def fitted_columns(result: Any) -> dict[str, Any]:
    """Fitted values, standard errors and 95 % intervals of the analysed run (``fit.*``,
    ``se.*``, ``lo.*``, ``hi.*``), with what else the report plots."""
    out: dict[str, Any] = {}
    for index, fits in sorted(result.hold_fits.items())[:1]:
        fit = fits[-1].resolved
        nan = math.nan
        _estimate(out, "G_e", fit.g_e, se := fit.stderr.get("G_e", nan), fit.g_e - Z95 * se,
                  fit.g_e + Z95 * se)
        # the material's amplitudes: the hold-start ones corrected for relaxation during the
        # ramp (what the truth holds); their standard errors scale with them
        corrected: Any = fit.extra.get("relax_ramp_corrected") or []
        for k, term in enumerate(fit.relax, start=1):
            g = float(corrected[k - 1]["G"]) if len(corrected) >= k else term.g
            ratio = g / term.g if term.g else 1.0
            for name, value, scale in ((f"G_{k}", g, ratio), (f"tau_{k}", term.tau, 1.0)):
                se = fit.stderr.get(name, nan) * scale
                _estimate(out, name, value, se, value - Z95 * se, value + Z95 * se)
        out["terms_resolved"] = max(fits[-1].terms_resolved, 0)
        # an unresolved fit is no result: coverage and bias leave the member out
        out["resolved"] = fit.is_resolved
        out["not_resolved"] = fit.reason
        out["held_s"] = float(result.holds[index].duration)
        touch = result.holds[index].overlap
        if touch is not None and touch.touch is not None:  # the ramp's refit (m)
            z0, se = touch.touch.position, touch.touch.stderr
            _estimate(out, "first_touch", z0, se, z0 - Z95 * se, z0 + Z95 * se)
    for _, model in sorted(result.model_fits.items())[:1]:
        for e in model.estimates:
            _estimate(out, e.name, e.value, e.stderr, e.lo, e.hi)
        # how the standard errors were made (ADR 0272): the lag-1 widening of the white-noise
        # covariance and the per-pass sandwich's s.e. over the white-noise one, per parameter
        out["fit.covariance_inflation"] = float(model.extra.get("covariance_inflation", math.nan))
        ratios: Any = model.extra.get("cluster_se_ratio") or {}
        for name, ratio in ratios.items():
            out[f"cluster_ratio.{name}"] = float(ratio)
        out["profile_refits"] = int(model.extra.get("profile_refits", 0))
        out["rms_h_over_noise"] = model.rms_h / model.noise_h if model.noise_h else math.nan
        out["rms_v_over_noise"] = model.rms_v / model.noise_v if model.noise_v else math.nan
    for _, ladder in sorted(result.ladders.items())[:1]:
        by_speed: dict[float, list[float]] = {}
        for r in ladder.results:
            if math.isfinite(r.ratio):
                by_speed.setdefault(float(r.speed), []).append(float(r.ratio))
        out["lclg_by_speed"] = json.dumps({f"{s:.6g}": sum(v) / len(v)
                                           for s, v in sorted(by_speed.items())})
    return out



def model_lc_ratio(r1: float, r2: float, overlap: float, material: Any, speed: float,
                   mu: float, unloading: str = "cutoff") -> float:
    """l_c / l_g of one fresh pass of the contact model at the true ``overlap``: the travel
    where F_perp > 0 (1 um steps), over the chord 2 psi0."""
    import numpy as np

    from gelrig.instrument.physics.sliding import SlidingGeometry, shear_pass

    geo = SlidingGeometry(r1, r2, overlap)
    sp = shear_pass(geo, material, speed, mu, dt=1e-6 / speed, unloading=unloading)
    inside = np.flatnonzero(sp.f_perp > 0)
    theta = sp.theta
    return float(theta[inside[-1]] - theta[inside[0]] + theta[1] - theta[0]) / geo.l_g


def pass_columns(result: Any, run_dir: Path, rig_spec: Any) -> dict[str, Any]:
    """The shear member's passes against its truth (issue 26: ``gelrig validate``'s per-pass
    claims): per pass (``passes``, JSON) direction, speed, overlap, l_g, l_c, mu, their
    errors and the outlier flags; and each error's worst pass: ``pass.lg_chord_rel_max``
    (l_g over the chord at the true overlap, the hidden touch gap less the pass's recorded
    gap, minus 1), ``pass.lc_error_max_m`` (l_c less the fresh-contact model's there),
    ``pass.lclg_error_max`` (l_c/l_g less the model's), ``pass.mu_rel_error_max`` (mu over
    the truth, minus 1), ``pass.lc_C_AC_max_m`` (|l_c(C) - l_c(AC)|), ``pass.outliers``."""
    import numpy as np

    from gelrig.instrument.analysis.shear_analysis import split_passes
    from gelrig.instrument.core.store import RunDirectory
    from gelrig.instrument.physics.sliding import SlidingGeometry
    from gelrig.simulators.mcr501.config import PAPER_MATERIAL

    out: dict[str, Any] = {}
    for index, ladder in sorted(result.ladders.items())[:1]:
        truth = rig_spec.simulator
        material = truth.material or PAPER_MATERIAL
        passes = {p.index: p for p in split_passes(RunDirectory(run_dir).read_step(index))}
        by_level: dict[tuple[float, float], dict[float, float]] = {}
        for r in ladder.results:
            by_level.setdefault((round(r.overlap, 9), r.speed), {})[r.direction] = r.l_c
        cache: dict[tuple[float, float], float] = {}
        rows = []
        for r in ladder.results:
            overlap = truth.touch_gap - float(np.median(passes[r.index].gap))
            chord = SlidingGeometry(truth.r1, truth.r2, overlap).l_g
            key = (round(overlap, 9), float(r.speed))
            if key not in cache:
                cache[key] = model_lc_ratio(truth.r1, truth.r2, overlap, material, r.speed,
                                            truth.mu, truth.unloading)
            pair = by_level[(round(r.overlap, 9), r.speed)]
            rows.append({
                "pass": r.index, "direction": "C" if r.direction > 0 else "AC",
                "speed_m_s": r.speed, "overlap_m": r.overlap, "true_overlap_m": overlap,
                "l_g_m": r.l_g, "l_c_m": r.l_c, "mu": r.mu, "mu_stderr": r.mu_stderr,
                "lg_chord_rel": r.l_g / chord - 1.0,
                "lc_error_m": r.l_c - cache[key] * chord,
                "lclg_error": r.ratio - cache[key],
                "mu_rel_error": r.mu / truth.mu - 1.0 if truth.mu else math.nan,
                "lc_C_AC_m": abs(pair[1.0] - pair[-1.0]) if len(pair) == 2 else math.nan,
                "flags": list(r.flags)})
        if not rows:
            continue

        def worst(name: str, rows: list[dict[str, Any]] = rows) -> float:
            values = [float(row[name]) for row in rows]
            return max(values, key=lambda v: abs(v) if math.isfinite(v) else math.inf)

        out["passes"] = json.dumps(rows, default=float)
        out["pass.lg_chord_rel_max"] = worst("lg_chord_rel")
        out["pass.lc_error_max_m"] = worst("lc_error_m")
        out["pass.lclg_error_max"] = worst("lclg_error")
        out["pass.mu_rel_error_max"] = worst("mu_rel_error")
        out["pass.lc_C_AC_max_m"] = worst("lc_C_AC_m")
        out["pass.outliers"] = sum(bool(row["flags"]) for row in rows)
    return out


def param_columns(member: MemberSpec, procedure: Procedure) -> dict[str, Any]:
    """The protocol parameters the campaign set, in SI (``param.*``; lists as JSON)."""
    out: dict[str, Any] = {}
    if member.params and member.protocol_table is None:  # a script's, as given
        for key, value in member.params.items():
            out[f"param.{key}"] = (json.dumps(value) if isinstance(value, list | tuple)
                                   else value)
        return out
    if not member.params or member.protocol_table is None:
        return out
    for key in member.params:
        head, _, fname = key.rpartition(".")
        index = (int(head[5:-1]) if head.startswith("step[") else
                 next(i for i, s in enumerate(procedure.steps) if s.name == head))
        value = procedure.steps[index].params.to_table()[fname]
        out[f"param.{key}"] = (json.dumps([float(v) for v in value])
                               if isinstance(value, tuple | list) else
                               (float(value) if value is not None else math.nan))
    return out


def run_member(member: MemberSpec) -> dict[str, Any]:
    """Run, analyse and describe one member; never raises (a failure is a record)."""
    start = time.perf_counter()
    record: dict[str, Any] = {
        "member_id": member.member_id, "index": member.index, "seed": member.seed,
        "variant": json.dumps(member.params, sort_keys=True),
        "truth_variant": json.dumps(member.truth, sort_keys=True),
        "status": "failed", "state": "", "error": ""}
    try:
        record.update(_run(member))
    except Exception as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        record["error"] = f"{type(exc).__name__}: {text}"[:500]
        record["traceback"] = traceback.format_exc()[-4000:]
    record["wall_s"] = time.perf_counter() - start
    return record


def _run(member: MemberSpec) -> dict[str, Any]:
    from gelrig.analyze_run import analyze_run
    from gelrig.factory import build_rig, twin_spec
    from gelrig.instrument.core.clock import VirtualClock
    from gelrig.protocols.host import closing_rig
    from gelrig.protocols.resolve import resolve_rig
    from gelrig.protocols.rigfile import ShearRigSpec

    source = f"member {member.member_id}"
    procedure = member_procedure(member)
    rig_spec = twin_spec(resolve_rig(member.rig_table, procedure, source))
    out: dict[str, Any] = {**truth_columns(rig_spec), **param_columns(member, procedure)}
    with _run_dir(member) as run_dir:
        with closing_rig(build_rig(rig_spec, VirtualClock(), in_process=True)) as rig:
            state, reason, safe = run_protocol(rig, procedure, run_dir, rig_spec,
                                               member.run_meta)
        out.update(safe)
        out["state"] = state
        if state != "completed":
            out["error"] = f"run {state}: {reason}"
            return out
        options: dict[str, Any] = {}
        if isinstance(rig_spec, ShearRigSpec):
            a, sim = member.analysis, rig_spec.simulator
            options = {"r1": sim.r1, "r2": sim.r2, "terms": a.terms,
                       "fit_geometry": a.fit_geometry, "anisotropic": a.anisotropic,
                       "fit_model": a.model_fit,
                       "unloading": sim.unloading if a.unloading == "truth" else a.unloading}
        result = analyze_run(run_dir, run_dir / "analysis", **options)
        out.update(fitted_columns(result))
        if isinstance(rig_spec, ShearRigSpec):
            out.update(pass_columns(result, run_dir, rig_spec))
        out["fit_unloading"] = options.get("unloading", "")
        out["problems"] = len(result.problems)
        out["status"] = "ok" if not result.problems else "incomplete"
        if result.problems:
            out["error"] = result.problems[0][:500]
    return out
