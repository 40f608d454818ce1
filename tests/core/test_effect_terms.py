"""An effect's term in a `WithEffects` model (`jaxfric._effect_model._term`): where all its
linear parameters are 0 (switched off, as a diagnosis holds most of its superset's
effects) the JVP skips the signals' tangents; the Jacobian (forward mode) and the gradient
(reverse mode) are the plain ones, for effects off and on, memoryless and with memory."""

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import _effect_model, effects, trajectories


@pytest.fixture(scope="module")
def case():
    t = np.arange(0.0, 3.0, 2e-3)
    x = trajectories.point_to_point(t, np.random.default_rng(3))
    stribeck = jaxfric.Stribeck(Fs=30.0, Fc=22.0, Vs=4e-3, delta=2.0)
    base = jaxfric.GMS.from_shape(jaxfric.PowerShape(l1=4e-6, n=2.5), stribeck, 80.0, 15.0, 5)
    model = base + (effects.FrictionLag(lag_gain=0.0, tau=0.05),  # off
                    effects.Cogging(period=1e-3, cog_sin=0.0, cog_cos=0.0),  # off
                    effects.Inertia(mass=0.0),  # off
                    effects.Drift(drift_rate=2e-3, drift_decay=0.1),  # on
                    effects.Asymmetry(asym=0.01))  # on
    motion = jaxfric.motion.make_motion(jnp.asarray(t), jnp.asarray(x),
                                        jnp.asarray(np.gradient(x, t))).consistent()
    return model, motion


def _flat(model):
    params, static = eqx.partition(model, eqx.is_inexact_array)
    y, unravel = jax.flatten_util.ravel_pytree(params)
    return y, lambda p: eqx.combine(unravel(p), static)


def _plain(monkeypatch, fn):
    with monkeypatch.context() as m:
        m.setattr(_effect_model, "_term", lambda e, s: e.term(s))
        return fn()


def test_jacobian_and_gradient_are_the_plain_ones(case, monkeypatch):
    model, motion = case
    y, build = _flat(model)
    w = jnp.cos(jnp.arange(motion.t.size))

    # `_simulate`, not `jaxfric.simulate`: traced anew at each call (not a cached program),
    # so that the plain terms are the ones traced in `_plain`
    def jac():
        return jax.jacfwd(lambda p: build(p)._simulate(motion).force)(y)

    def grad():
        return jax.grad(lambda p: jnp.sum(w * build(p)._simulate(motion).force))(y)

    new_j, plain_j = jac(), _plain(monkeypatch, jac)
    assert np.all(np.isfinite(new_j))
    # the off effects' linear parameters have columns (a fit can switch them on)
    assert np.sum(np.any(np.asarray(plain_j) != 0, axis=0)) > y.size - 10
    np.testing.assert_allclose(new_j, plain_j, rtol=1e-12,
                               atol=1e-12 * float(jnp.abs(plain_j).max()))
    np.testing.assert_allclose(grad(), _plain(monkeypatch, grad), rtol=1e-10, atol=1e-9)
