"""The same contact on every clock (issue 24): the short compression protocol recorded through
the whole simulated rig (simulator, wire, driver, runner, recorder) on any clock, and what it
measured, for comparison against the virtual run.

The short protocol: contact search from 5.6 mm (0.5 mm probes at 0.3 mm/s), the paper's 6 %
ramp at 0.002 /s, a hold, 2 mm retract.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gelrig.instrument.analysis.contact_residual import residual
from gelrig.instrument.core.clock import clock_from_spec
from gelrig.instrument.core.errors import GelrigError
from gelrig.instrument.core.store import RunDirectory, read_step
from gelrig.instrument.physics.contact import FloatArray
from gelrig.protocols.rigfile import CompressionRigSpec, default_rig, load_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import record_run

log = logging.getLogger("gelrig.clock_check")

#: The short protocol's steps (issue 24): contact search from 5.6 mm, the paper's 6 % ramp
#: at 0.002 /s, a hold, 2 mm retract; ``{hold}``, ``{confirm}`` and ``{rate}`` are filled in.
SHORT_STEPS: tuple[dict[str, Any], ...] = (
    {"kind": "compression_contact_search", "name": "contact search", "start": "5.6 mm",
     "probe": "0.5 mm", "speed": "0.3 mm/s", "threshold": "5 mN", "retract": "0.5 mm"},
    {"kind": "ramp_hold", "name": "ramp and hold", "strain": 0.06,
     "strain_rate": "0.002 /s", "retract": "2 mm", "terms": 1},
)


@dataclass(frozen=True)
class ClockRun:
    """What one run of the short protocol measured, for comparison across clocks."""

    clock: str
    search_touch: float
    ramp_touch: float
    #: the ramp refit's standard error (m), from the run's own data
    ramp_touch_se: float
    depth: float
    #: rms and worst |recorded - model| force (N) over the whole ramp-hold-retract step,
    #: and the recorded force's noise (:func:`recorded_noise`)
    residual_rms: float
    residual_worst: float
    noise: float
    #: samples whose plate position was flagged as untrusted (``position_flag``)
    flagged: int
    t: FloatArray
    position: FloatArray
    force: FloatArray
    #: run.json's ``time_base``: each instrument's time mapping and its uncertainty
    time_base: dict[str, Any]
    #: the residual's course over the hold: rms over the hold's 12 bins of their mean
    #: residual (N), as recorded and less the ADC's expected bias (:func:`adc_bias`)
    hold_drift: float = math.nan
    hold_drift_adc: float = math.nan
    #: the samples in each of those bins (their mean's noise is the noise over its root)
    hold_bin_samples: int = 0


def timing_rig(folder: Path, seed: int = 1, stage_latency: float = 1e-3,
               noise: str | None = None, daq: bool = True, updates: bool = False) -> Path:
    """The built-in compression rig with the instruments' timing switched on (the simulated
    USB-6001's :data:`~gelrig.simulators.usb6001.device.DOCUMENTED` drift, USB transfers,
    latency and jitter; a KDC101 reply latency of ``stage_latency`` s), written into
    ``folder``; ``seed`` the noise's, ``noise`` its rms (default the rig's, the paper's);
    ``daq`` False leaves the USB-6001 ideal; ``updates`` has the stage driver take the
    KDC101's status updates (every 100 ms) as position reports."""
    from gelrig.simulators.usb6001.device import DOCUMENTED, DaqTiming

    timing = DOCUMENTED if daq else DaqTiming()

    text = default_rig("compression").read_text()
    text = re.sub(r"(?m)^seed = \d+$", (
        f"seed = {seed}\ndaq_drift_ppm = {timing.drift_ppm:g}\n"
        f"daq_latency = \"{timing.latency:g} s\"\n"
        f"daq_jitter = \"{timing.jitter:g} s\"\ndaq_transfer = {timing.transfer}\n"
        f"stage_reply_latency = \"{stage_latency:g} s\""), text)
    if noise is not None:
        text = re.sub(r'(?m)^noise = "[^"]*"', f'noise = "{noise}"', text)
    if updates:
        text = text.replace("[stage]\n", "[stage]\nstatus_updates = true\n", 1)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "rig_timing.toml"
    path.write_text(text)
    return path


def record_short_run(folder: Path, clock: str, hold: str = "60 s", confirm: int = 2,
                     rate: str = "100 Hz", rig: Path | None = None, strain: float = 0.06,
                     strain_rate: str = "0.002 /s") -> ClockRun:
    """Record the short protocol on the built-in simulated compression rig (or ``rig``) on
    ``clock`` into ``folder`` and measure it (``strain``, ``strain_rate``: the ramp's, the
    paper's 6 % at 0.002 /s)."""
    search, ramp = (dict(s) for s in SHORT_STEPS)
    search.update(confirm=confirm)
    ramp.update(hold=hold, rate=rate, strain=strain, strain_rate=strain_rate)
    spec = load_rig(rig or default_rig("compression"))
    assert isinstance(spec, CompressionRigSpec)
    # the sample is the simulated rig's own sphere, stated (no size is a default)
    sample = {"name": "the simulated rig's sphere",
              "diameter": spec.simulator.sphere_diameter}
    protocol = parse_protocol({"protocol": {"name": "clock invariance", "rig": "compression"},
                               "sample": sample, "step": [search, ramp]})
    folder.mkdir(parents=True, exist_ok=True)
    run = RunDirectory.create(folder / "run", {"protocol": protocol.table, "rig": spec.table})
    record_run(protocol, spec, clock_from_spec(clock), run, show=False)
    steps = run.read_metadata()["steps"]
    cols = read_step(run.step_file(steps[1]))
    t, z, f = cols["t_s"], cols["position_m"], cols["force_N"]
    res = residual(spec.simulator, t, z, f, cols["position_flag"])
    drift, drift_adc, per_bin = hold_drift(spec, t, z, f)
    results = steps[1]["results"]
    return ClockRun(clock, steps[0]["results"]["first_touch_m"],
                    results["first_touch_ramp_m"],
                    float(results.get("first_touch_ramp_se_m", math.nan)),
                    results["measured_depth_m"],
                    float(np.sqrt(np.mean(res ** 2))) if res.size else math.nan,
                    float(np.max(np.abs(res))) if res.size else math.nan,
                    recorded_noise(spec), int(np.count_nonzero(cols["position_flag"])), t, z, f,
                    dict(run.read_metadata().get("time_base", {})), drift, drift_adc,
                    per_bin)


def adc_bias(spec: CompressionRigSpec, force: FloatArray) -> FloatArray:
    """The expected recorded force less the true ``force`` (N) of the simulated chain: the
    USB-6001 rounds the input (true force through the chain, its offset and the rig's
    Gaussian noise) to 14-bit codes, and the tare removed the mean code at zero force. With a
    noise below a code (0.3 mN) the mean of the codes is not the input: the difference follows
    the force through each code, a slow course over a hold whose force relaxes (issue 24,
    item 5)."""
    from scipy.stats import norm

    from gelrig.simulators.usb6001.config import SIM_OFFSET
    from gelrig.simulators.usb6001.device import DeviceSpec

    sens = spec.force.chain.sensitivity
    lsb, sigma = DeviceSpec().lsb, spec.simulator.noise * sens
    offset = spec.force.chain.offset + SIM_OFFSET

    def mean_code(v: FloatArray) -> FloatArray:
        codes = (np.round(v / lsb)[..., None] + np.arange(-8, 9)) * lsb
        if sigma <= 0:
            return np.asarray(np.round(v / lsb) * lsb, dtype=float)
        d = codes - v[..., None]
        p = norm.cdf((d + lsb / 2) / sigma) - norm.cdf((d - lsb / 2) / sigma)
        return np.asarray((p * codes).sum(-1), dtype=float)

    v = np.asarray(force, dtype=float) * sens + offset
    zero = mean_code(np.array([offset]))[0] - offset
    return np.asarray((mean_code(v) - v - zero) / sens, dtype=float)


def hold_drift(spec: CompressionRigSpec, t: FloatArray, z: FloatArray, f: FloatArray,
               bins: int = 12) -> tuple[float, float, int]:
    """The force residual's course over the hold (the samples at the deepest position): rms
    over ``bins`` time bins of their mean residual (N), as recorded and less
    :func:`adc_bias`, and the samples per bin."""
    from gelrig.instrument.analysis.contact_residual import model_force

    ok = np.isfinite(z)
    hold = ok & (np.abs(z - np.nanmax(z)) < 1e-9)
    if np.count_nonzero(hold) < 10 * bins:
        return math.nan, math.nan, 0
    model = model_force(spec.simulator, t, z)[hold]
    res = f[hold] - model
    th = t[hold]
    k = np.minimum((bins * (th - th[0]) / (th[-1] - th[0])).astype(int), bins - 1)
    binned = np.array([res[k == i].mean() for i in range(bins)])
    bias = adc_bias(spec, model)
    expected = np.array([bias[k == i].mean() for i in range(bins)])
    return (float(np.sqrt(np.mean(binned ** 2))),
            float(np.sqrt(np.mean((binned - expected) ** 2))), int(np.count_nonzero(hold)) // bins)


def recorded_noise(spec: CompressionRigSpec) -> float:
    """The recorded force's noise (N rms): the truth's, and the ADC's quantization (one
    14-bit code of the USB-6001 is 0.3 mN through the nominal chain)."""
    from gelrig.simulators.usb6001.device import DeviceSpec

    lsb = DeviceSpec().lsb / spec.force.chain.sensitivity
    return math.hypot(spec.simulator.noise, lsb / math.sqrt(12.0))




def record_ladder_levels(folder: Path, clock: str, overlaps: int = 2,
                         speeds: tuple[str, ...] = ("2.38e-5 m/s", "2.37e-4 m/s"),
                         wait: str = "10 s", seed: int | None = None) -> list[dict[str, float]]:
    """The paper's shear protocol, with a shorter ladder (``overlaps`` levels from the paper's
    first, ``speeds``), recorded on the built-in simulated shear rig (its noise seeded by
    ``seed``, default the rig file's) on ``clock`` and analysed: one row per (overlap, speed)
    with l_g, l_c (C, AC) and mu, and ``touch_gap_m``, the contact search's (issue 24, item
    6)."""
    from gelrig.analyze_run import analyze_run
    from gelrig.protocols.spec import load_protocol, paper_protocol

    table = load_protocol(paper_protocol("shear")).table
    steps = [dict(s) for s in table["step"]]
    steps[1].update(overlaps=overlaps, speeds=list(speeds), wait=wait)
    protocol = parse_protocol({"protocol": dict(table["protocol"]), "sample": table["sample"],
                               "step": steps})
    folder.mkdir(parents=True, exist_ok=True)
    rig = default_rig("shear")
    if seed is not None:
        text = re.sub(r"(?m)^seed = \d+$", f"seed = {seed}", rig.read_text())
        rig = folder / "rig_shear.toml"
        rig.write_text(text)
    spec = load_rig(rig)
    run = RunDirectory.create(folder / "run", {"protocol": protocol.table, "rig": spec.table})
    record_run(protocol, spec, clock_from_spec(clock), run, show=False)
    meta = run.read_metadata()
    if any(st.get("status") != "completed" for st in meta["steps"]):
        raise GelrigError(f"the shear ladder on {clock} did not complete: "
                          f"{meta.get('reason', 'no reason recorded')}")
    result = analyze_run(run.path, folder / "analysis")
    touch = float(meta["steps"][0]["results"]["touch_gap_m"])
    ladder = result.ladders[1]
    for problem in ladder.problems:  # a pass left out: its level may have no result
        log.warning("shear ladder on %s: %s", clock, problem)
    return [dict(row, touch_gap_m=touch) for row in ladder.levels()]


__all__ = ["SHORT_STEPS", "ClockRun", "adc_bias", "hold_drift", "record_ladder_levels",
           "record_short_run", "recorded_noise", "timing_rig"]
