"""The GMS's structured JVP (`jaxfric._models.gms._elements_jvp`: one forward pass per
shared parameter plus one for every element's own nu and one for its own k) gives the
derivatives of the plain JVP of the element scan, column for column: on a motion with
rests, reversals and slips, for forward mode (a fit's Jacobian), reverse mode (a gradient),
under vmap, and with respect to the positions (where it falls back to the plain JVP)."""

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import trajectories
from jaxfric._models import gms


def _plain(model, motion):
    return jnp.sum(model._element_forces(motion), axis=-1)


@pytest.fixture(scope="module")
def case():
    t = np.arange(0.0, 4.0, 2e-3)
    x = trajectories.point_to_point(t, np.random.default_rng(3))  # moves, dwells, reversals
    stribeck = jaxfric.Stribeck(Fs=30.0, Fc=22.0, Vs=4e-3, delta=2.0)
    model = jaxfric.GMS.from_shape(jaxfric.PowerShape(l1=4e-6, n=2.5), stribeck, 80.0,
                                   15.0, 7)
    motion = jaxfric.motion.make_motion(jnp.asarray(t), jnp.asarray(x),
                                        jnp.asarray(np.gradient(x, t))).consistent()
    return model, motion


def _jacobians(model, motion, fn):
    params, static = eqx.partition(model, eqx.is_inexact_array)
    y, unravel = jax.flatten_util.ravel_pytree(params)
    return jax.jacfwd(lambda p: fn(eqx.combine(unravel(p), static), motion))(y)


def test_the_jacobian_is_the_plain_jvps(case):
    model, motion = case
    new = _jacobians(model, motion, gms._elements)
    plain = _jacobians(model, motion, _plain)
    # every column but sigma2's (the viscous term is outside the element scan)
    assert np.any(np.asarray(plain) != 0.0, axis=0).sum() == plain.shape[1] - 1
    np.testing.assert_allclose(new, plain, rtol=1e-12, atol=1e-12 * float(jnp.abs(plain).max()))


def test_the_gradient_is_the_plain_one(case):
    model, motion = case
    w = jnp.cos(jnp.arange(motion.t.size))  # a loss weighting every sample differently

    def grad(fn):
        g = jax.grad(lambda m: jnp.sum(w * fn(m, motion)))(model)
        return jax.flatten_util.ravel_pytree(g)[0]

    g = grad(gms._elements)
    assert np.all(np.isfinite(g))  # at rest and at every reversal of the motion
    np.testing.assert_allclose(g, grad(_plain), rtol=1e-12, atol=1e-9)


def test_under_vmap_over_models(case):
    model, motion = case
    models = jax.vmap(lambda c: eqx.tree_at(lambda m: m.C, model, c))(jnp.array([5.0, 15.0]))

    def tangent(fn):
        one = jax.tree.map(jnp.ones_like, model)
        return jax.vmap(lambda m: jax.jvp(lambda mm: fn(mm, motion), (m,), (one,))[1])(models)

    np.testing.assert_allclose(tangent(gms._elements), tangent(_plain), rtol=1e-12,
                               atol=1e-9)


def test_with_respect_to_the_positions(case):
    model, motion = case
    dx = jnp.sin(jnp.arange(motion.t.size)) * 1e-9
    t_motion = eqx.tree_at(lambda m: m.x, jax.tree.map(jnp.zeros_like, motion), dx)
    zero = jax.tree.map(jnp.zeros_like, model)
    new = jax.jvp(gms._elements, (model, motion), (zero, t_motion))[1]
    plain = jax.jvp(_plain, (model, motion), (zero, t_motion))[1]
    np.testing.assert_array_equal(new, plain)
