"""`jaxfric.simulate_many`: a batch of parameter sets (Monte-Carlo) and/or of motions gives
the forces of the independent reference (tests/reference.py) item by item, the same as
`jax.vmap` over `simulate`, and keeps gradients."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import paper

from .. import reference as ref
from ..helpers import nested_path, ref_kwargs, sine_path


TOL = 1e-6  # N, as tests/core/test_reference.py


def _sets(model, B, seed=0):
    """B parameter sets: every array leaf times 1 + 0.05 N(0, 1)."""
    params, static = eqx.partition(model, eqx.is_array)
    rng = np.random.default_rng(seed)
    batched = jax.tree.map(
        lambda a: jnp.asarray(a * (1 + 0.05 * rng.standard_normal((B, *jnp.shape(a))))),
        params)
    return batched, static


def _item(batched, static, j):
    return eqx.combine(jax.tree.map(lambda a: a[j], batched), static)


@pytest.mark.parametrize("make", [paper.two_state, paper.gms5])
def test_parameter_sets_match_reference(make):
    batched, static = _sets(make(), 5)
    t, x = nested_path()
    # chunk 2 of 5: full chunks and a remainder
    out = jaxfric.simulate_many(eqx.combine(batched, static), t, x, chunk=2, full_output=True)
    assert out.force.shape == (5, t.size) and out.overflow.shape == (5,)
    for j in range(5):
        model = _item(batched, static, j)
        r = (ref.two_state if isinstance(model, jaxfric.TwoState) else ref.gms)(
            t, x, None, **ref_kwargs(model))
        err = np.max(np.abs(np.asarray(out.force[j]) - r["F"]))
        assert err < TOL, f"set {j}: max |F - F_ref| = {err:.3e} N"


def test_motions_and_both_batched_match_simulate():
    model = paper.two_state()
    t, x, v = sine_path()
    t2, x2 = nested_path()
    n = min(t.size, t2.size)
    T = np.stack([t[:n], t2[:n], t[:n]])
    X = np.stack([x[:n], x2[:n], -x[:n]])
    V = np.stack([v[:n], np.gradient(x2[:n], t2[:n]), -v[:n]])
    F = jaxfric.simulate_many(model, T, X, V, model_axis=None, chunk=2)
    for j in range(3):
        np.testing.assert_allclose(F[j], jaxfric.simulate(model, T[j], X[j], V[j]),
                                   atol=1e-12, rtol=0)
    batched, static = _sets(model, 3, seed=1)
    F = jaxfric.simulate_many(eqx.combine(batched, static), T, X, chunk=8)
    for j in range(3):
        np.testing.assert_allclose(F[j], jaxfric.simulate(_item(batched, static, j), T[j],
                                                          X[j]), atol=1e-12, rtol=0)


@pytest.mark.slow  # about 20 s: compiling the gradient of the chunked map
def test_grad_and_jit_match_vmap():
    batched, static = _sets(paper.two_state(), 4)
    t, x = nested_path()

    def loss_many(p):
        return jnp.sum(jaxfric.simulate_many(eqx.combine(p, static), t, x, chunk=3,
                                             max_reversals=64) ** 2)

    def loss_vmap(p):
        return jnp.sum(jax.vmap(lambda q: jaxfric.simulate(eqx.combine(q, static), t, x,
                                                           max_reversals=64))(p) ** 2)

    g1 = jax.jit(jax.grad(loss_many))(batched)
    g2 = jax.grad(loss_vmap)(batched)
    for a, b in zip(jax.tree.leaves(g1), jax.tree.leaves(g2)):
        assert np.all(np.isfinite(a))
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * float(np.max(np.abs(b))))


def test_bad_inputs_raise():
    model = paper.two_state()
    t, x = nested_path()
    with pytest.raises(ValueError, match="nothing to batch"):
        jaxfric.simulate_many(model, t, x, model_axis=None)
    batched, static = _sets(model, 3)
    with pytest.raises(ValueError, match="batch axis"):
        jaxfric.simulate_many(eqx.combine(batched, static), np.stack([t, t]), np.stack([x, x]))
    with pytest.raises(ValueError, match="strictly increasing"):
        jaxfric.simulate_many(model, np.stack([t, t[::-1]]), np.stack([x, x]), model_axis=None)
    X = np.stack([x, x])
    X[1, 3] = np.inf
    with pytest.raises(ValueError, match=r"x has a non-finite value at \[1, 3\]"):
        jaxfric.simulate_many(model, np.stack([t, t]), X, model_axis=None)


def test_reversal_bound_of_rows_is_the_largest():
    t, x = nested_path()
    small = 1e-3 * np.sin(2 * np.pi * t / t[-1])  # one reversal
    rng = np.random.default_rng(0)
    noisy = x + 1e-7 * rng.standard_normal(t.size)  # hundreds of reversals
    bounds = [jaxfric.reversal_bound(t, a) for a in (small, noisy)]
    assert bounds[0] == 64 and bounds[1] > 64
    assert jaxfric.reversal_bound(np.stack([t, t]), np.stack([small, noisy])) == bounds[1]


def test_load_and_acceleration_inputs_reach_every_item():
    """A model reading the load and the acceleration (`LoadFriction`, `Inertia`): a batch of
    parameter sets on one motion, and a batch of motions each with its own load and
    acceleration, give `simulate`'s forces item by item; without `a` they differ (the
    backward difference of `v` is not the given acceleration)."""
    from jaxfric import effects as fx

    model = paper.two_state() + (fx.Inertia(mass=2.0), fx.LoadFriction(k_load=0.05))
    t, x, v = sine_path(n=800)
    a = np.gradient(v, t) + np.cos(5.0 * t)  # a measured column, with its own errors
    load = 10.0 * np.sin(3.0 * t)
    batched, static = _sets(model, 3, seed=4)
    many = jaxfric.simulate_many(eqx.combine(batched, static), t, x, v, chunk=2, load=load,
                                 a=a)
    for j in range(3):
        one = jaxfric.simulate(_item(batched, static, j), t, x, v, load=load, a=a)
        np.testing.assert_allclose(many[j], one, rtol=0, atol=1e-9)
    plain = jaxfric.simulate(_item(batched, static, 0), t, x, v, load=load)
    assert np.max(np.abs(plain - many[0])) > 1e-3
    # Gradients with respect to every parameter set stay finite through a standstill
    # (v exactly 0) and the sine's reversals.
    xs, vs = np.r_[np.zeros(20), x[:-20]], np.r_[np.zeros(20), v[:-20]]
    grads = jax.grad(lambda p: jnp.sum(jaxfric.simulate_many(
        eqx.combine(p, static), t, xs, vs, chunk=2, load=load, a=a)))(batched)
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in jax.tree.leaves(grads))
    assert float(jnp.abs(grads.effects[0].mass).sum()) > 0  # the mass reads the given a
    # Motions (B, n), each with its own load and acceleration.
    T, X, V, A, L = (np.stack([u, u, u]) for u in (t, x, v, a, load))
    L = L * np.array([[0.5], [1.0], [2.0]])
    A = A * np.array([[1.0], [0.0], [-1.0]])
    many = jaxfric.simulate_many(model, T, X, V, model_axis=None, chunk=2, load=L, a=A)
    for j in range(3):
        one = jaxfric.simulate(model, t, x, v, load=L[j], a=A[j])
        np.testing.assert_allclose(many[j], one, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="same shape"):
        jaxfric.simulate_many(model, T, X, V, model_axis=None, a=a)
    bad = A.copy()
    bad[2, 7] = np.nan
    with pytest.raises(ValueError, match=r"a has a non-finite value at \[2, 7\]"):
        jaxfric.simulate_many(model, T, X, V, model_axis=None, a=bad)
