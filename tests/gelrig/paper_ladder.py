"""The paper's shear protocol recorded on the built-in simulated rig, and its figures.

Shared by the end-to-end feature tests and docs/decisions/0140: the run goes through the
simulator, the wire (pyvisa-py over TCP), the driver, the runner and the recorder; the
figures come from ``gelrig analyze`` (:func:`gelrig.analyze_run.analyze_run`) and, for the
chord at the true overlap, from the recorded gap and the rig file's hidden touch gap.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.analyze_run import AnalysisResult, analyze_run
from gelrig.instrument.analysis.shear_analysis import split_passes
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.store import RunDirectory
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.sliding import SlidingGeometry, shear_pass
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import ShearRigSpec, default_rig, parse_rig
from gelrig.protocols.spec import load_protocol, paper_protocol, parse_protocol
from gelrig.terminal import record_run


def rig(**simulator: Any) -> ShearRigSpec:
    """The built-in shear rig with ``simulator`` entries overridden (e.g. carry_history)."""
    from gelrig.instrument.core.fields import read_toml

    table = read_toml(default_rig("shear"), "rig file")
    table = copy.deepcopy(table)
    table["simulator"].update(simulator)
    spec = parse_rig(table, "paper ladder rig")
    assert isinstance(spec, ShearRigSpec)
    return spec


def protocol(overlaps: int | None = None, speeds: list[str] | None = None) -> Any:
    """The paper's shear protocol, optionally with fewer overlaps (the deepest kept) or
    speeds."""
    spec = load_protocol(paper_protocol("shear"))
    if overlaps is None and speeds is None:
        return spec
    table = copy.deepcopy(spec.table)
    ladder = table["step"][1]
    if overlaps is not None:
        first = float(str(ladder["first_overlap"]).split()[0])
        step = float(str(ladder["overlap_step"]).split()[0])
        ladder["first_overlap"] = f"{first + step * (ladder['overlaps'] - overlaps):.4f} mm"
        ladder["overlaps"] = overlaps
    if speeds is not None:
        ladder["speeds"] = speeds
    return parse_protocol(table, "reduced paper protocol")


def record(path: Path, spec: ShearRigSpec, proto: Any) -> RunDirectory:
    """Run ``proto`` on the simulated ``spec`` in virtual time, recorded to ``path``."""
    run = RunDirectory.create(path, {"protocol": proto.table, "rig": spec.table})
    state, _ = record_run(proto, spec, VirtualClock(), run, show=False)
    assert state is RunState.COMPLETED
    return run


def analyse(run: RunDirectory, out: Path, fit_model: bool = False) -> AnalysisResult:
    """``gelrig analyze`` of the run (the ladder-wide model fit only when asked: it is slow)."""
    return analyze_run(run.path, out, fit_model=fit_model)


def levels(run: RunDirectory, result: AnalysisResult, spec: ShearRigSpec
           ) -> list[dict[str, float]]:
    """One row per (overlap, speed): the analysis's figures plus the truth's.

    Adds the true overlap (hidden touch gap minus the recorded gap), the chord 2 psi0 there,
    the C and AC troughs and F_v peaks, and l_c/l_g of the fresh-contact model at the true
    overlap (the span where F_perp > 0, over 2 psi0).
    """
    truth = spec.simulator
    (index, analysis), = result.ladders.items()
    passes = {p.index: p for p in split_passes(run.read_step(index))}
    by_level: dict[tuple[float, float], list[Any]] = {}
    for r in analysis.results:
        by_level.setdefault((round(r.overlap, 9), r.speed), []).append(r)
    rows = []
    for row in analysis.levels():
        group = by_level[(row["overlap_m"], row["speed_m_s"])]
        gaps = [float(np.median(passes[r.index].gap)) for r in group]
        overlap = truth.touch_gap - float(np.mean(gaps))
        geo = SlidingGeometry(truth.r1, truth.r2, overlap)
        cw = next(r for r in group if r.direction > 0)
        acw = next(r for r in group if r.direction < 0)
        row.update({
            "true_overlap_m": overlap, "chord_m": geo.l_g,
            "trough_C_N": cw.f_h_trough, "trough_AC_N": acw.f_h_trough,
            "f_v_peak_C_N": cw.f_v_peak, "f_v_peak_AC_N": acw.f_v_peak,
            "model_l_c_over_l_g": model_ratio(geo, truth.material, row["speed_m_s"],
                                              truth.mu, truth.unloading),
        })
        rows.append(row)
    return rows


def model_ratio(geo: SlidingGeometry, material: Material | None, speed: float, mu: float,
                unloading: str = "cutoff") -> float:
    """l_c / l_g of one fresh pass of the model: the travel where F_perp > 0, over 2 psi0."""
    from gelrig.simulators.mcr501.config import PAPER_MATERIAL

    sp = shear_pass(geo, material or PAPER_MATERIAL, speed, mu, dt=1e-6 / speed,
                    unloading=unloading)
    inside = np.flatnonzero(sp.f_perp > 0)
    theta = sp.theta
    return float(theta[inside[-1]] - theta[inside[0]] + theta[1] - theta[0]) / geo.l_g


def table(rows: list[dict[str, float]], overlap_mm: float = 0.78) -> list[str]:
    """The issue's table at one nominal overlap, one line per speed."""
    out = ["| speed (m/s) | l_g (mm) | chord (mm) | abs(l_c(C) - l_c(AC)) (um) | trough C / AC "
           "(mN) | F_v peak C / AC (mN) | mu C / AC | l_c/l_g (model) |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if not math.isclose(r["overlap_m"], overlap_mm * 1e-3, abs_tol=1e-7):
            continue
        out.append(
            f"| {r['speed_m_s']:.3g} | {r['l_g_m'] * 1e3:.3f} | {r['chord_m'] * 1e3:.3f} | "
            f"{abs(r['l_c_C_m'] - r['l_c_AC_m']) * 1e6:.1f} | {r['trough_C_N'] * 1e3:.2f} / "
            f"{r['trough_AC_N'] * 1e3:.2f} | {r['f_v_peak_C_N'] * 1e3:.1f} / "
            f"{r['f_v_peak_AC_N'] * 1e3:.1f} | {r['mu_C']:.4f} / {r['mu_AC']:.4f} | "
            f"{r['l_c_over_l_g']:.4f} ({r['model_l_c_over_l_g']:.4f}) |")
    return out
