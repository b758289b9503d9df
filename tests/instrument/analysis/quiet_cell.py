"""A plate-compression ramp and hold as the twin records it, without the twin's instruments:
the contact model drives the load-cell chain (its conditioner pole and noise, the simulator's
own :class:`LoadCellSignal`), the USB-6001's 14-bit codes and a tare, then ``analyse_hold``
(what ``gelrig analyze`` fits). The cheap path of the coverage studies (docs/decisions/0270):
the stage is ideal and the contact search's first touch is off by a seeded 1 um.
"""

from __future__ import annotations

import numpy as np

from gelrig.instrument.analysis.hold_analysis import HoldAnalysis, analyse_hold
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.physics.contact import Material
from gelrig.instrument.physics.paper import DEPTH_HOLD, R_COMPRESSION, RAMP_SPEED
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.simulators.usb6001.config import SIM_OFFSET
from gelrig.simulators.usb6001.device import DeviceSpec
from gelrig.simulators.usb6001.signals import LoadCellSignal

TOUCH = 6.2e-3
APPROACH = 0.1e-3
TARE = 1.0
#: Spread (m) of the contact search's first touch: where the ramp ends varies per seed.
SEARCH_SD = 1e-6


def record(material: Material, noise: float, rate: float, hold: float, seed: int,
           quantised: bool = True) -> tuple[np.ndarray, ...]:
    """(t, force, recorded overlap, plate position) from the ramp's start to the hold's end."""
    chain = LoadCellChain(offset=SIM_OFFSET)
    found = TOUCH + SEARCH_SD * np.random.default_rng([seed, 7]).standard_normal()
    ramp = (DEPTH_HOLD + APPROACH) / RAMP_SPEED
    n_tare = int(TARE * rate)
    t = np.arange(n_tare + int((ramp + hold) * rate)) / rate - TARE

    def plate(ts: np.ndarray) -> np.ndarray:
        return found - APPROACH + np.clip(ts, 0.0, ramp) * RAMP_SPEED

    contact = PlateSphereContact(material, R_COMPRESSION, TOUCH, plate, vectorized=True)
    volts = LoadCellSignal(contact, chain, noise * chain.sensitivity, seed).volts(
        float(t[0]), 1.0 / rate, t.size)
    if quantised:
        lsb = DeviceSpec().lsb
        volts = np.round(volts / lsb) * lsb
    force = chain.newtons(volts, float(np.mean(volts[:n_tare])))
    z = plate(t)
    return t[n_tare:], force[n_tare:], z[n_tare:] - found, z[n_tare:]


def analysed(material: Material, noise: float, rate: float, hold: float, seed: int,
             terms: tuple[int, ...] = (1,), quantised: bool = True) -> HoldAnalysis:
    """The hold of :func:`record` analysed as ``gelrig analyze`` does."""
    t, f, d, z = record(material, noise, rate, hold, seed, quantised)
    return analyse_hold(t, f, d, R_COMPRESSION, DEPTH_HOLD, hold, terms=terms, position=z)


def z_scores(material: Material, analysis: HoldAnalysis) -> dict[str, float]:
    """(fit - truth) / reported s.e. of every parameter of the resolved fit with as many terms
    as the truth (the amplitudes ramp-corrected, as a campaign compares them); empty if the
    data resolve fewer terms."""
    fit = analysis.fits[-1].resolved
    if len(fit.relax) != len(material.relax):
        return {}
    out = {"G_e": (fit.g_e - material.g_e) / fit.stderr["G_e"]}
    corrected = fit.extra.get("relax_ramp_corrected") or []
    for k, (term, true) in enumerate(zip(fit.relax, material.relax, strict=True), start=1):
        g = float(corrected[k - 1]["G"]) if corrected else term.g
        out[f"G_{k}"] = (g - true.g) / (fit.stderr[f"G_{k}"] * g / term.g)
        out[f"tau_{k}"] = (term.tau - true.tau) / fit.stderr[f"tau_{k}"]
    return out
