"""The MDR contact (physics.md 1b) against the hereditary model, Ting (1966), Hertz limits,
the closed-form recovery of one arm, and its own per-sample reference."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.optimize import brentq

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.physics.contact import Material, hertz_prefactor, normal_force
from gelrig.instrument.physics.mdr import MdrContact, mdr_contact, mdr_force

R = 5e-3
SLS = Material.of(4e3, [(2e4, 10.0)])
TWO = Material.of(4e3, [(2e4, 3.0), (5e3, 0.4)])


def wavy(seed, n=1500):
    """Variable steps; loads, unloads, separates and reloads several times."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.05, n))
    delta = 1e-3 * np.sin(t / 8.0) + 2e-4 + 1e-4 * np.sin(1.3 * t + seed)
    return t, delta


def stepped(material, t, delta, **kw):
    contact = MdrContact(material, R, **kw)
    return np.array([contact.step(a, b) for a, b in zip(t, delta)]), contact


# ------------------------------------------------------------------ batch = per-sample rules


@pytest.mark.parametrize("material", [SLS, TWO, Material(4e3)],
                         ids=["1 term", "2 terms", "elastic"])
def test_event_driven_batch_equals_the_per_sample_update(material):
    t, delta = wavy(3)
    ref, ref_contact = stepped(material, t, delta, delta_max=1.3e-3)
    batch = MdrContact(material, R, delta_max=1.3e-3)
    detail = batch.block_detail(t, delta)
    assert ref.max() > 0 and np.any(ref == 0)  # the history does separate
    np.testing.assert_allclose(detail.force, ref, rtol=0, atol=1e-10 * ref.max())
    np.testing.assert_allclose(batch.surface, ref_contact.surface, rtol=0, atol=1e-14)
    assert batch.contact_radius == ref_contact.contact_radius


def test_blocks_of_any_length_give_the_same_record():
    t, delta = wavy(5)
    whole = mdr_force(t, delta, TWO, R, delta_max=1.3e-3)
    contact = MdrContact(TWO, R, delta_max=1.3e-3)
    parts = np.concatenate([contact.block(t[i : i + 37], delta[i : i + 37])
                            for i in range(0, t.size, 37)])
    np.testing.assert_allclose(parts, whole, rtol=0, atol=1e-10 * whole.max())


def test_block_uniform_equals_block_with_the_times_spelled_out():
    dt = 0.02
    delta = wavy(2, 800)[1]
    a = MdrContact(SLS, R, delta_max=1.3e-3)
    first = a.block_uniform(delta[:300], dt)
    rest = a.block_uniform(delta[300:], dt)
    b = MdrContact(SLS, R, delta_max=1.3e-3).block(np.arange(delta.size) * dt, delta)
    np.testing.assert_allclose(np.concatenate((first, rest)), b, rtol=0, atol=1e-10 * b.max())


def test_reset_is_a_fresh_contact():
    t, delta = wavy(1, 400)
    contact = MdrContact(SLS, R, delta_max=1.3e-3)
    first = contact.block(t, delta)
    contact.reset()
    assert contact.contact_radius == 0 and not contact.surface.any()
    np.testing.assert_array_equal(contact.block(t, delta), first)


# ------------------------------------------------------------------ growing contact = Lee-Radok


def test_growing_contact_equals_the_hereditary_model_and_converges_with_elements():
    t = np.linspace(0.0, 20.0, 4001)
    delta = 1e-3 * (t / 20.0) ** 1.3  # only grows (not linearly)
    cut = normal_force(t, delta, TWO, R)
    errors = []
    for n in (50, 100, 200, 400):
        f = MdrContact(TWO, R, elements=n, delta_max=1e-3).block(t, delta)
        errors.append(np.max(np.abs(f - cut)) / cut.max())
    assert errors[-1] < 1e-5
    # second order in the element spacing: each doubling cuts the error about fourfold
    assert all(later < earlier / 3 for earlier, later in itertools.pairwise(errors))


def test_growing_contact_radius_is_the_hertz_radius_within_one_element():
    t = np.linspace(0.0, 10.0, 1001)
    delta = 8e-4 * t / 10.0
    contact = MdrContact(SLS, R, delta_max=8e-4)
    radius = contact.block_detail(t, delta).radius
    assert np.max(np.abs(radius - np.sqrt(R * delta))) <= contact.dx


def test_overlap_beyond_the_grid_grows_it_and_stays_exact():
    t = np.linspace(0.0, 10.0, 2001)
    delta = 1.5e-3 * t / 10.0
    contact = MdrContact(SLS, R, elements=200, delta_max=5e-4)
    f = contact.block(t, delta)
    assert contact.elements > 200
    cut = normal_force(t, delta, SLS, R)
    assert np.max(np.abs(f - cut)) / cut.max() < 1e-4


# ------------------------------------------------------------------ Ting (1966)


def ting(t, material, v, t_max):
    """Ting's receding-contact solution for a sphere, ramp up then down at speed v, for any
    Prony modulus G(t).

    While loading a = sqrt(R delta) and F is the Lee-Radok integral. After t_max the contact
    radius is a(t1) of the loading branch, t1 from int_{t1}^{t} G(t - s) d delta(s) = 0, i.e.
    Phi(t - t1) = 2 Phi(t - t_max) with Phi(u) = int_0^u G; the force is the Lee-Radok
    integral over the loading branch up to t1 only. Quadrature, no discretisation.
    """
    ge, terms = material.g_e, material.relax

    def phi(u):
        return ge * u + sum(r.g * r.tau * -math.expm1(-u / r.tau) for r in terms)

    def kernel(s, tn):
        return sum(r.g * math.exp(-(tn - s) / r.tau) for r in terms) * 1.5 * v**1.5 * math.sqrt(s)

    k = hertz_prefactor(R, material.nu)
    force, radius = np.zeros(t.size), np.zeros(t.size)
    for n, tn in enumerate(t):
        if tn <= t_max:
            t1 = tn
        else:
            target = 2.0 * phi(tn - t_max)
            if phi(tn) <= target:
                continue  # the contact has closed
            t1 = brentq(lambda s, tn=tn, target=target: phi(tn - s) - target, 0.0, t_max,
                        xtol=1e-14)
        visc = quad(kernel, 0.0, t1, args=(tn,), epsabs=0.0, epsrel=1e-12)[0]
        force[n] = k * (ge * (v * t1) ** 1.5 + visc)
        radius[n] = math.sqrt(R * v * t1)
    return force, radius


@pytest.mark.parametrize(
    ("material", "t_max"),
    [(SLS, 2.0), (SLS, 10.0), (SLS, 40.0), (TWO, 5.0)],  # short, equal, long against tau
)
def test_receding_contact_reproduces_ting(material, t_max):
    v = 1e-3 / t_max
    t = np.linspace(0.0, 2.0 * t_max, 4001)
    delta = v * np.where(t <= t_max, t, 2.0 * t_max - t)
    every = slice(None, None, 5)  # the quadrature oracle at every 5th sample
    f_ting, a_ting = ting(t[every], material, v, t_max)
    contact = MdrContact(material, R, delta_max=1e-3)
    got = contact.block_detail(t, delta)
    assert np.max(np.abs(got.force[every] - f_ting)) < 2e-5 * f_ting.max()
    assert np.max(np.abs(got.radius[every] - a_ting)) <= contact.dx
    # and the cutoff model does not: the comparison has something to find
    cut = normal_force(t, delta, material, R)[every]
    assert np.max(np.abs(cut - f_ting)) > 1e-2 * f_ting.max()


# ------------------------------------------------------------------ no negative force


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    terms=st.integers(0, 2),
    steps=st.integers(2, 300),
)
def test_force_is_never_negative_zero_when_apart_and_equal_to_the_reference(seed, terms, steps):
    rng = np.random.default_rng(seed)
    material = Material.of(
        float(rng.uniform(1e3, 2e4)),
        [(float(rng.uniform(0, 5e4)), float(10 ** rng.uniform(-2, 3))) for _ in range(terms)],
    )
    t = np.cumsum(rng.exponential(0.1, steps))
    delta = np.cumsum(rng.normal(0.0, 1e-4, steps))  # a random walk through contact and out
    detail = MdrContact(material, R, elements=60, delta_max=5e-4).block_detail(t, delta)
    assert np.all(detail.force >= 0)
    assert np.all(detail.force[delta < 0] == 0)
    assert np.all(detail.radius[delta < 0] == 0)
    # the event search finds every switch the per-sample update makes
    ref, _ = stepped(material, t, delta, elements=60, delta_max=5e-4)
    np.testing.assert_allclose(detail.force, ref, rtol=0, atol=1e-8 * max(ref.max(), 1e-30))


# ------------------------------------------------------------------ elastic limits


def load_unload(n=801):
    t = np.linspace(0.0, 2.0, n)
    return t, 1e-3 * np.sin(np.pi * t / 2.0) ** 2  # in and back out smoothly


def test_infinite_tau_is_hertz_with_the_instantaneous_modulus():
    t, delta = load_unload()
    f = MdrContact(Material.of(4e3, [(2e4, math.inf)]), R, delta_max=1e-3).block(t, delta)
    hertz = hertz_prefactor(R) * 2.4e4 * delta**1.5
    np.testing.assert_allclose(f, hertz, rtol=0, atol=2e-5 * hertz.max())


def test_vanishing_tau_is_hertz_with_the_equilibrium_modulus():
    t, delta = load_unload(301)
    f = MdrContact(Material.of(4e3, [(2e4, 1e-7)]), R, delta_max=1e-3).block(t, delta)
    hertz = hertz_prefactor(R) * 4e3 * delta**1.5
    np.testing.assert_allclose(f, hertz, rtol=0, atol=2e-5 * hertz.max())


def test_long_tau_tends_to_the_instantaneous_hertz():
    t, delta = load_unload()
    hertz = hertz_prefactor(R) * 2.4e4 * delta**1.5
    gaps = [np.max(np.abs(MdrContact(Material.of(4e3, [(2e4, tau)]), R, delta_max=1e-3)
                          .block(t, delta) - hertz)) for tau in (1e2, 1e4, 1e6)]
    assert gaps[0] > 10 * gaps[1] > 100 * gaps[2]


# ------------------------------------------------------------------ recovery out of contact


def test_a_free_element_recovers_on_the_retardation_time_of_one_arm():
    ge, g1, tau = 4e3, 2e4, 10.0
    contact = MdrContact(Material.of(ge, [(g1, tau)]), R, delta_max=1e-3)
    contact.block(np.linspace(0.0, 30.0, 301), np.full(301, 1e-3))  # hold: dashpots creep
    contact.block(np.array([30.01]), np.array([-1e-3]))  # pull off within one step
    assert contact.contact_radius == 0
    w0 = contact.surface
    assert w0.max() > 1e-4  # a dent remains
    later = np.linspace(30.02, 90.0, 50)
    contact.block(later, np.full(later.size, -1e-3))
    retardation = tau * (ge + g1) / ge
    np.testing.assert_allclose(contact.surface, w0 * math.exp(-(later[-1] - 30.01) / retardation),
                               rtol=1e-9, atol=1e-18)


def test_the_dent_recovers_for_the_next_contact():
    """A second indentation after a short rest meets a dent (less force); after a rest much
    longer than the retardation time it meets a fresh surface (the same force as the first)."""
    t = np.linspace(0.0, 20.0, 401)
    delta = 8e-4 * np.sin(np.pi * t / 20.0)
    fresh = mdr_force(t, delta, SLS, R, delta_max=8e-4)
    forces = {}
    for rest in (5.0, 2000.0):
        contact = MdrContact(SLS, R, delta_max=8e-4)
        contact.block(t, delta)
        contact.block(np.array([20.0 + rest]), np.array([-1e-4]))
        forces[rest] = contact.block(t + 20.0 + rest + 0.05, delta)
    assert forces[5.0].max() < 0.95 * fresh.max()
    np.testing.assert_allclose(forces[2000.0], fresh, rtol=0, atol=1e-6 * fresh.max())


# ------------------------------------------------------------------ construction and input


def test_adapter_has_the_normal_contact_shape():
    contact = mdr_contact(SLS, R, nu=0.3, elements=100)
    assert isinstance(contact, MdrContact)
    assert contact.nu == 0.3 and contact.elements == 100
    t = np.linspace(0.0, 1.0, 11)
    f = contact.block(t, 1e-4 * t)
    # nu enters through k = G / (1 - nu), as in K = 4 sqrt(R) / (3 (1 - nu))
    assert f[-1] == pytest.approx(mdr_force(t, 1e-4 * t, SLS, R, elements=100)[-1] * 0.5 / 0.7,
                                  rel=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"radius": 0.0}, "radius"), ({"nu": 1.0}, "nu"), ({"elements": 2}, "elements"),
     ({"delta_max": -1.0}, "delta_max")],
)
def test_bad_construction_names_the_field(kwargs, field):
    args = {"material": SLS, "radius": R, **kwargs}
    with pytest.raises(ConfigError) as info:
        MdrContact(**args)
    assert info.value.field == field


def test_time_going_backwards_is_refused():
    contact = MdrContact(SLS, R)
    contact.step(1.0, 1e-4)
    with pytest.raises(ValueError, match="backwards"):
        contact.step(0.5, 1e-4)
    with pytest.raises(ValueError, match="decrease"):
        contact.block(np.array([2.0, 1.0]), np.array([1e-4, 1e-4]))


def test_small_blocks_and_save_restore_give_the_same_record():
    t, delta = wavy(4, 600)
    whole = mdr_force(t, delta, TWO, R, delta_max=1.3e-3)
    contact = MdrContact(TWO, R, delta_max=1.3e-3)
    parts = []
    for i in range(0, t.size, 5):  # below the size where the per-sample update takes over
        saved = contact.snapshot()
        contact.step(t[i] + 0.5, 2e-3)  # a peek ahead (past the grid: it grows) ...
        contact.restore(saved)  # ... forgotten
        parts.append(contact.block(t[i : i + 5], delta[i : i + 5]))
    np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0, atol=1e-10 * whole.max())
