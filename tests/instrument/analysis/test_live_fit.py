"""The live relaxation fit (instrument/analysis/live_fit.py): binned refits agree with the offline
fit of
the same samples, the forecast, the stopping rule, and its honesty under the paper's noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gelrig.instrument.analysis.live_fit import LiveFit, StopRule
from gelrig.instrument.analysis.live_fit_sim import modulus_noise, simulate_hold
from gelrig.instrument.analysis.relaxation import fit_relaxation
from gelrig.instrument.physics import paper


def _record(material: object, hold: float, rate: float, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    t = np.arange(round(hold * rate)) / rate
    g = material.modulus(t) + rng.normal(0.0, modulus_noise(), t.size)  # type: ignore[attr-defined]
    return t, g


@pytest.mark.parametrize(("material", "terms", "hold"), [
    (paper.PLATES, 1, 1500.0), (paper.SHELL, 2, 3000.0), (paper.PLATES, 2, 3000.0)])
def test_live_fit_converges_to_the_offline_fit_of_the_same_data(
        material: object, terms: int, hold: float) -> None:
    t, g = _record(material, hold, 100.0, seed=3)
    live = LiveFit(terms, hold, 100.0)
    for start in range(0, t.size, 400):  # 4 s blocks, as the hold reads them
        live.add(t[start:start + 400], g[start:start + 400])
        elapsed = t[min(start + 400, t.size) - 1] + 0.01
        if live.due(elapsed):
            live.refit(elapsed)
    state = live.refit(hold)
    assert state is not None
    offline = fit_relaxation(t, g, terms=terms)
    shown = offline.resolved
    assert state.terms_resolved == offline.terms_resolved
    assert state.g_e == pytest.approx(shown.g_e, rel=1e-3)
    for k, (a, b) in enumerate(zip(state.relax, shown.relax, strict=True), 1):
        err = shown.stderr[f"tau_{k}"]
        assert abs(a.tau - b.tau) < 0.1 * err  # bins of 1 s against tau >= 172 s
        assert state.stderr[f"tau_{k}"] == pytest.approx(err, rel=0.05)
    assert len(live.history) >= 30  # every few percent of the hold


def test_forecast_predicts_the_final_uncertainty() -> None:
    sim = simulate_hold(paper.PLATES, 1, 3000.0, 100.0, seed=5)
    final = sim.history[-1].relative["tau_1"]
    mid = next(s for s in sim.history if s.elapsed >= 1000.0)
    assert mid.forecast["tau_1"] == pytest.approx(final, rel=0.3)
    assert mid.relative["tau_1"] > 2 * final  # not just the current error restated


def test_rule_needs_two_refits_in_a_row_terms_and_min_hold() -> None:
    sim = simulate_hold(paper.PLATES, 1, 3000.0, 100.0, seed=2)
    rule = StopRule(0.02)
    first = next(i for i, s in enumerate(sim.history) if rule.met(s))
    assert not rule.done(sim.history[:first + 1])
    assert rule.done(sim.history[:first + 2]) == rule.met(sim.history[first + 1])
    late = sim.history[first + 1]
    assert not StopRule(0.02, min_hold=late.elapsed + 1).met(late)
    assert not StopRule(0.02, terms=2).met(late)  # one term resolved on the plate


#: Seeds of the test (the benchmark runs more: benchmarks/bench_live_fit.py --study).
SEEDS = 12


def test_adaptive_hold_is_honest_under_the_papers_noise() -> None:
    """Stopping on a noise fluctuation would leave the stated error too small: over repeated
    holds the final tau must lie within 2 standard errors of the truth about 95 % of the time
    (at least 10 of 12 here: a binomial tail of 2 % if the coverage were 95 %)."""
    rule = StopRule(0.02)
    inside, ended = 0, []
    for seed in range(SEEDS):
        sim = simulate_hold(paper.PLATES, 1, 3000.0, 100.0, seed=100 + seed, rule=rule)
        assert sim.reason == "target"
        last = sim.history[-1]
        ended.append(sim.ended)
        z = (last.tau - 1413.0) / last.stderr["tau_1"]
        inside += abs(z) <= 2.0
        assert math.isfinite(z)
    assert inside >= SEEDS - 2
    assert max(ended) < 3000.0


def test_band_holds_the_truth_and_narrows_as_the_hold_goes_on() -> None:
    sim = simulate_hold(paper.PLATES, 1, 3000.0, 100.0, seed=9)
    early = next(s for s in sim.history if s.elapsed >= 500.0)
    late = sim.history[-1]
    for state in (early, late):
        t, g, sd = state.curve
        assert t[0] == 0.0 and t[-1] == pytest.approx(state.elapsed)
        assert np.all(np.isfinite(sd)) and np.all(sd > 0)
        z = np.abs(g - paper.PLATES.modulus(t)) / sd
        assert np.mean(z <= 3.0) >= 0.9
        assert state.data[0].size <= 300
    assert np.median(late.curve[2]) < 0.5 * np.median(early.curve[2])


def test_correlated_noise_widens_the_errors_as_the_variance_of_a_mean() -> None:
    """Issue 30: a load cell with an Ornstein-Uhlenbeck part beside its white noise (as
    bring-up measures it): the mean over a span is less certain than the white-noise count
    says, by :func:`correlated_inflation` (checked against 4000 simulated records)."""
    from scipy.signal import lfilter

    from gelrig.instrument.analysis.live_fit import correlated_inflation

    rate, tau, span, white, corr = 100.0, 0.5, 20.0, 0.35, 0.4
    m = int(rate * span)
    phi = math.exp(-1.0 / (rate * tau))
    rng = np.random.default_rng(7)
    drive = rng.standard_normal((4000, m)) * corr * math.sqrt(1 - phi * phi)
    start = phi * corr * rng.standard_normal((4000, 1))
    ou = lfilter([1.0], [1.0, -phi], drive, axis=1, zi=start)[0]
    means = (ou + white * rng.standard_normal(ou.shape)).mean(axis=1)
    measured = float(np.std(means)) / math.sqrt((white**2 + corr**2) / m)
    assert correlated_inflation(white, corr, tau, rate, span) == pytest.approx(measured,
                                                                               rel=0.05)
    assert correlated_inflation(white, 0.0, tau, rate, span) == 1.0


def test_a_live_fit_with_an_inflation_reports_errors_that_much_wider() -> None:
    t = np.arange(0.0, 600.0, 0.01)
    g = paper.PLATES.modulus(t) + np.random.default_rng(3).normal(0, modulus_noise(), t.size)
    states = []
    for k in (1.0, 2.5):
        fit = LiveFit(1, 600.0, 100.0, inflation=k)
        fit.add(t, g)
        state = fit.refit(600.0)
        assert state is not None
        states.append(state)
    plain, wide = states
    assert wide.g_e == plain.g_e  # the estimates are the same
    for name, err in plain.stderr.items():
        assert wide.stderr[name] == pytest.approx(2.5 * err)
    assert wide.tau_relative == pytest.approx(2.5 * plain.tau_relative)
    assert wide.forecast["tau_1"] == pytest.approx(2.5 * plain.forecast["tau_1"])
    assert np.allclose(wide.curve[2], 2.5 * plain.curve[2], equal_nan=True)
