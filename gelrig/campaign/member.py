"""One campaign member: the rig twin with the member's hidden truth, its protocol run in
virtual time into a run directory, the run analysed, one flat record back.

Runs on a Dask worker (or in process): it takes a :class:`~gelrig.campaign.spec.MemberSpec`
(plain tables, so a remote worker needs no campaign file) and never raises; a member that
fails returns its record with ``status = "failed"`` and the error in one line.

:func:`run_protocol` is the one place a member's protocol runs, chosen by its reference: a
protocol file (or ``paper:...``), or a script (loaded by path on the worker, called with the
member's parameters).
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
from instrument.errors import ConfigError

#: z of a two-sided 95 % interval: a hold fit reports standard errors only.
Z95 = 1.959963984540054
#: Fitted parameters compared with the truth, in the order the report shows them.
FITTED = ("G_e", "G_1", "tau_1", "G_2", "tau_2", "mu", "touch_gap", "lower_angle")


def run_protocol(rig: Any, ref: str, table: dict[str, Any] | None, run_dir: Path,
                 rig_spec: Any, params: dict[str, Any] | None = None) -> tuple[str, str]:
    """Run the protocol named by ``ref`` on the built ``rig`` into a new run directory
    ``run_dir``; returns (final state, reason). A script (``ref`` a ``.py`` path) is called
    with ``params``; a protocol file's parameters are in ``table`` already."""
    from gelrig.session import LOG_NAME, metadata, run_logging
    from instrument.store import RunDirectory
    from protocols.procedure import Procedure
    from protocols.session import RecordedRun
    from protocols.spec import parse_protocol

    protocol: Procedure
    if ref.endswith(SCRIPT_SUFFIXES):
        from protocols.script import load_script

        protocol = load_script(ref).with_params(**(params or {}))
    elif table is None:
        raise ConfigError("[campaign] protocol", ref, "a protocol file's table is needed")
    else:
        protocol = parse_protocol(table, ref)
    run = RunDirectory.create(run_dir, metadata(protocol, rig_spec, "virtual"))
    with run_logging(run.path / LOG_NAME):  # the run's log, not the worker's stderr
        recorded = RecordedRun(rig, protocol).record(run)
        recorded.runner.watched = False  # nobody watches: no live refits of a fixed hold
        state = recorded.run()
    return state.value, recorded.reason


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
    from protocols.rigfile import ShearRigSpec
    from simulators.mcr501.config import PAPER_MATERIAL
    from simulators.usb6001.rig import PLATES

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
        out["held_s"] = float(result.holds[index].duration)
    for _, model in sorted(result.model_fits.items())[:1]:
        for e in model.estimates:
            _estimate(out, e.name, e.value, e.stderr, e.lo, e.hi)
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


def param_columns(member: MemberSpec) -> dict[str, Any]:
    """The protocol parameters the campaign set, in SI (``param.*``; lists as JSON)."""
    from protocols.spec import parse_protocol

    out: dict[str, Any] = {}
    if member.params and member.protocol_table is None:  # a script's, as given
        for key, value in member.params.items():
            out[f"param.{key}"] = (json.dumps(value) if isinstance(value, list | tuple)
                                   else value)
        return out
    if not member.params or member.protocol_table is None:
        return out
    protocol = parse_protocol(member.protocol_table, member.protocol_ref)
    for key in member.params:
        head, _, fname = key.rpartition(".")
        index = (int(head[5:-1]) if head.startswith("step[") else
                 next(i for i, s in enumerate(protocol.steps) if s.name == head))
        value = protocol.steps[index].params.to_table()[fname]
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
    from instrument.clock import VirtualClock
    from protocols.rigfile import ShearRigSpec, parse_rig
    from protocols.safestop import bounded

    source = f"member {member.member_id}"
    rig_spec = twin_spec(parse_rig(member.rig_table, source))
    out: dict[str, Any] = {**truth_columns(rig_spec), **param_columns(member)}
    with _run_dir(member) as run_dir:
        rig = build_rig(rig_spec, VirtualClock(), in_process=True)
        try:
            state, reason = run_protocol(rig, member.protocol_ref, member.protocol_table,
                                         run_dir, rig_spec, member.params)
        finally:
            bounded(rig.close, 10.0, "closing the rig")
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
        out["fit_unloading"] = options.get("unloading", "")
        out["problems"] = len(result.problems)
        out["status"] = "ok" if not result.problems else "incomplete"
        if result.problems:
            out["error"] = result.problems[0][:500]
    return out
