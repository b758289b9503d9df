"""The contact model against limits, closed forms and brute-force oracles (physics.md 1)."""

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import dawsn

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import (
    Material,
    NormalContact,
    RelaxationTerm,
    effective_radius,
    hereditary,
    hertz_prefactor,
    normal_force,
    normal_force_uniform,
)
from gelrig.instrument.physics.contact_models import make_contact

R = 5e-3


def brute_force(t, delta, material, radius):
    """O(N^2) oracle: the exact integral for x linear within each step, summed directly
    (the history carried across separations)."""
    k = hertz_prefactor(radius, material.nu)
    x = np.maximum(delta, 0.0) ** 1.5
    xs = np.concatenate(([0.0], x))
    ts = np.concatenate(([t[0]], t))
    out = np.empty(t.size)
    for n in range(t.size):
        hat = 0.0
        for term in material.relax:
            acc = 0.0
            for j in range(1, n + 2):
                dx = xs[j] - xs[j - 1]
                dt = ts[j] - ts[j - 1]
                if dt == 0:
                    acc += dx * math.exp(-(t[n] - ts[j]) / term.tau)
                else:
                    late = math.exp(-(t[n] - ts[j]) / term.tau)
                    early = math.exp(-(t[n] - ts[j - 1]) / term.tau)
                    acc += dx / dt * term.tau * (late - early)
            hat += term.g * acc
        out[n] = max(0.0, k * (material.g_e * x[n] + hat))
    return out


@pytest.mark.parametrize("terms", [1, 2, 3])
def test_recursion_equals_brute_force_variable_dt(terms):
    rng = np.random.default_rng(terms)
    t = np.cumsum(rng.uniform(0.001, 0.7, 150))
    delta = 1e-3 * np.sin(t / 8.0) + 2e-4  # loads, unloads, separates, reloads
    material = Material.of(4e3, [(2e4, 3.0), (5e3, 0.4), (1e3, 40.0)][:terms])
    np.testing.assert_allclose(normal_force(t, delta, material, R, carry_history=True),
                               brute_force(t, delta, material, R), rtol=1e-10, atol=1e-15)


def fresh_oracle(t, delta, material, radius):
    """Each contact on its own: the brute force over each run of overlap > 0, started from
    the apart sample before it (x = 0, no history); 0 where apart."""
    out = np.zeros(t.size)
    inside = delta > 0
    n = 0
    while n < t.size:
        if not inside[n]:
            n += 1
            continue
        end = n
        while end < t.size and inside[end]:
            end += 1
        lo = max(n - 1, 0)
        out[n:end] = brute_force(t[lo:end], delta[lo:end], material, radius)[n - lo:]
        n = end
    return out


@pytest.mark.parametrize("terms", [1, 2])
def test_each_contact_starts_fresh_by_default(terms):
    rng = np.random.default_rng(10 + terms)
    t = np.cumsum(rng.uniform(0.001, 0.7, 200))
    delta = 1e-3 * np.sin(t / 8.0) + 2e-4  # three contacts, separated
    material = Material.of(4e3, [(2e4, 30.0), (5e3, 4.0)][:terms])
    want = fresh_oracle(t, delta, material, R)
    np.testing.assert_allclose(normal_force(t, delta, material, R), want,
                               rtol=1e-10, atol=1e-15)
    # streamed one sample at a time, in blocks, and on a uniform grid: the same
    stepper = make_contact(material, R)
    stepped = np.array([stepper.step(a, b) for a, b in zip(t, delta, strict=True)])
    np.testing.assert_allclose(stepped, want, rtol=1e-10, atol=1e-15)
    chunks = make_contact(material, R)
    chunked = np.concatenate([chunks.block(t[i:i + 37], delta[i:i + 37])
                              for i in range(0, t.size, 37)])
    np.testing.assert_allclose(chunked, want, rtol=1e-10, atol=1e-15)
    tu = np.arange(400) * 0.5
    du = 1e-3 * np.sin(tu / 8.0) + 2e-4
    np.testing.assert_allclose(normal_force_uniform(du, 0.5, material, R),
                               fresh_oracle(tu, du, material, R), rtol=1e-10, atol=1e-15)
    # the carried history differs: the later contacts meet a negative hidden force
    carried = normal_force(t, delta, material, R, carry_history=True)
    later = t > 60.0
    assert np.max(np.abs(carried[later] - want[later])) > 0.01 * np.max(want)


def test_reset_snapshot_and_the_factory():
    material = Material.of(4e3, [(2e4, 30.0)])
    contact = make_contact(material, R)
    contact.block(np.linspace(0, 10, 11), np.linspace(0, 1e-3, 11))
    saved = contact.snapshot()
    ahead = contact.step(11.0, 8e-4)
    contact.restore(saved)
    assert contact.step(11.0, 8e-4) == ahead
    contact.reset()
    new = make_contact(material, R)
    new.step(11.0, 0.0)
    assert contact.step(12.0, 8e-4) == new.step(12.0, 8e-4)  # as a contact with no history
    mdr = make_contact(material, R, "mdr")  # fresh per contact too (physics.md 1)
    mdr.block(np.array([0.0, 5.0, 10.0]), np.array([0.0, 8e-4, 0.0]))
    again = make_contact(material, R, "mdr")
    again.step(10.0, 0.0)
    assert mdr.step(12.0, 8e-4) == again.step(12.0, 8e-4)
    with pytest.raises(ConfigError):
        make_contact(material, R, "ting")


def test_recursion_converges_to_quadrature_of_the_hereditary_integral():
    """Smooth overlap: the recursion tends to the integral computed by adaptive quadrature."""
    tau, v = 2.5, 1e-4
    def x_dot(s: float) -> float:
        d = v * s * (1 + 0.5 * math.sin(s))
        dd = v * (1 + 0.5 * math.sin(s) + 0.5 * s * math.cos(s))
        return 1.5 * math.sqrt(d) * dd
    t_end = 6.0
    exact = quad(lambda s: math.exp(-(t_end - s) / tau) * x_dot(s), 0.0, t_end, limit=200)[0]
    rng = np.random.default_rng(0)
    steps = rng.uniform(0.5, 1.5, 4000)
    t = np.concatenate(([0.0], np.cumsum(steps / steps.sum() * t_end)))
    d = v * t * (1 + 0.5 * np.sin(t))
    h = hereditary(np.diff(t, prepend=0.0), d**1.5, tau)
    assert h[-1] == pytest.approx(exact, rel=1e-5)


def test_tau_infinite_is_hertz_with_instantaneous_modulus():
    t = np.linspace(0, 100, 1001)
    delta = 1e-3 * np.sin(t / 30) ** 2
    slow = Material.of(4e3, [(2e4, 1e15)])
    exact = Material.of(4e3, [(2e4, math.inf)])
    hertz = Material.of(2.4e4)
    f_hertz = normal_force(t, delta, hertz, R)
    np.testing.assert_allclose(normal_force(t, delta, slow, R), f_hertz, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(normal_force(t, delta, exact, R), f_hertz, rtol=1e-12, atol=1e-15)


def test_tau_to_zero_is_hertz_with_equilibrium_modulus():
    t = np.linspace(0, 100, 1001)
    delta = 1e-3 * np.sin(t / 30) ** 2
    fast = Material.of(4e3, [(2e4, 1e-9)])
    np.testing.assert_allclose(normal_force(t, delta, fast, R),
                               normal_force(t, delta, Material.of(4e3), R), rtol=1e-6, atol=1e-12)


def test_ramp_then_hold_matches_closed_form():
    """Plate ramp x = (v t)^1.5 to T, then hold.

    h(T) = 1.5 v^1.5 tau^1.5 (sqrt a - D(sqrt a)) with a = T/tau and D Dawson's integral.
    """
    v, big_t, tau, g_e, g_1 = 3.7e-5, 30.0, 150.0, 7000.0, 900.0
    material = Material.of(g_e, [(g_1, tau)])
    t = np.concatenate((np.linspace(0, big_t, 30001), big_t + np.arange(1, 5001) * 0.1))
    delta = np.minimum(v * t, v * big_t)
    force = normal_force(t, delta, material, R)
    a = np.minimum(t, big_t) / tau
    h_ramp = 1.5 * v**1.5 * tau**1.5 * (np.sqrt(a) - dawsn(np.sqrt(a)))
    h = h_ramp * np.exp(-np.maximum(t - big_t, 0.0) / tau)
    expected = hertz_prefactor(R) * (g_e * delta**1.5 + g_1 * h)
    np.testing.assert_allclose(force[1:], expected[1:], rtol=2e-6)


def test_streaming_step_block_and_uniform_agree():
    material = Material.of(4e3, [(2e4, 20.0), (3e3, 2.0)])
    t = np.arange(2000) * 0.05
    delta = 1e-3 * np.abs(np.sin(t / 10))
    whole = normal_force(t, delta, material, R)
    stepper = NormalContact(material, R)
    stepped = np.array([stepper.step(a, b) for a, b in zip(t, delta, strict=True)])
    chunked_state = NormalContact(material, R)
    chunked = np.concatenate([chunked_state.block(t[i:i + 333], delta[i:i + 333])
                              for i in range(0, t.size, 333)])
    uniform = normal_force_uniform(delta, 0.05, material, R)
    for other in (stepped, chunked, uniform):
        np.testing.assert_allclose(other, whole, rtol=1e-11, atol=1e-15)


def test_history_decays_while_apart_and_cutoff_is_on_output_only():
    material = Material.of(4e3, [(2e4, 50.0)])
    contact = NormalContact(material, R, carry_history=True)
    contact.block(np.linspace(0, 10, 101), np.linspace(0, 1e-3, 101))
    # Unload quickly: the hereditary part goes negative, the output is clipped at zero.
    elastic, hat = contact.block_components(np.linspace(10.1, 11, 10), np.linspace(9e-4, 0, 10))
    assert np.any(elastic + hat < 0)
    assert contact.h[0] < 0
    h_apart = contact.h[0]
    contact.block(np.array([111.0]), np.array([-1e-4]))  # apart for 100 s: only decays
    assert contact.h[0] == pytest.approx(h_apart * math.exp(-100.0 / 50.0), rel=1e-9)
    fresh = NormalContact(material, R)  # the default: the state ends with the contact
    fresh.block(np.linspace(0, 10, 101), np.linspace(0, 1e-3, 101))
    fresh.block(np.linspace(10.1, 11, 10), np.linspace(9e-4, 0, 10))
    assert fresh.h[0] == 0.0


def test_first_sample_loads_instantaneously():
    material = Material.of(4e3, [(2e4, 50.0)])
    f = normal_force(np.array([0.0]), np.array([1e-3]), material, R)
    assert f[0] == pytest.approx(hertz_prefactor(R) * 2.4e4 * 1e-3**1.5)


def test_geometry_helpers():
    assert effective_radius(2.0, 2.0) == 1.0
    assert effective_radius(3.0) == 3.0
    assert hertz_prefactor(1.0, 0.5) == pytest.approx(8 / 3)


@pytest.mark.parametrize("make", [
    lambda: Material.of(-1.0),
    lambda: Material.of(1e3, nu=1.0),
    lambda: Material.of(1e3, nu=-0.1),
    lambda: RelaxationTerm(1e3, 0.0),
    lambda: RelaxationTerm(-1.0, 1.0),
    lambda: hertz_prefactor(0.0),
    lambda: effective_radius(-1.0, 1.0),
])
def test_bad_parameters_raise_config_error(make):
    with pytest.raises(ConfigError):
        make()


def test_time_going_backwards_is_refused():
    contact = NormalContact(Material.of(1e3, [(1e3, 1.0)]), R)
    contact.step(1.0, 1e-4)
    with pytest.raises(ValueError, match="backwards"):
        contact.step(0.5, 1e-4)
    with pytest.raises(ValueError, match="decrease"):
        contact.block(np.array([2.0, 1.5]), np.array([1e-4, 1e-4]))


@pytest.mark.parametrize("terms", [0, 1, 2])
@pytest.mark.parametrize("pattern", ["starts-apart", "separates", "apart-at-end", "in-contact"])
def test_the_uniform_fast_path_equals_the_per_contact_path(terms, pattern):
    """block_uniform (one filter pass per contact run) against block with the same times (the
    exact per-contact recursion), whole and streamed in blocks that start and end apart."""
    n, dt = 5000, 1e-3
    t = np.arange(n) * dt
    delta = {
        "starts-apart": np.minimum(t * 2e-4, 1e-4),  # the paper's ramp-hold: overlap 0 first
        "separates": 1e-4 * np.sin(t * 9.0),
        "apart-at-end": 1e-4 * np.sin(t * 0.7),
        "in-contact": 1e-4 * (1.1 + np.sin(t * 3.0)),
    }[pattern]
    material = Material.of(4e3, [(2e4, 0.3), (5e3, 0.02)][:terms])
    exact = NormalContact(material, R).block(t, delta)
    np.testing.assert_allclose(normal_force_uniform(delta, dt, material, R), exact,
                               rtol=1e-12, atol=1e-12 * np.max(exact))
    streamed = NormalContact(material, R)
    cuts = [0, 1, 17, 700, 701, 2600, 4999, n]
    parts = [streamed.block_uniform(delta[a:b], dt) for a, b in itertools.pairwise(cuts)]
    np.testing.assert_allclose(np.concatenate(parts), exact, rtol=1e-12,
                               atol=1e-12 * np.max(exact))
    assert streamed.t_last == pytest.approx(t[-1], rel=1e-12)
