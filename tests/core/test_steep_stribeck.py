"""A steep Stribeck curve (``delta`` in the hundreds: a model given for simulation may
have any ``delta``; a fit stays below `jaxfric._stribeck.DELTA_MAX`) at speeds of a few
``Vs``: ``(|v|/Vs)**delta`` overflows there while ``exp(-(|v|/Vs)**delta)`` is exactly 0.
The force is ``Fc`` and its derivatives are finite (``inf * 0`` made them NaN, which
stopped every later fit at its first step), on the JAX path and in the forward kernel
alike, and the curve's values are unchanged elsewhere."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import _kernel, paper


STEEP = jaxfric.Stribeck(Fs=24.0, Fc=22.0, Vs=0.005, delta=500.0)


def test_magnitude_is_fc_with_finite_gradients_beyond_the_overflow():
    v = jnp.asarray([0.0, 0.004, 0.005, 0.0051, 0.02, 0.05, 1.0])
    params, static = eqx.partition(STEEP, eqx.is_inexact_array)
    jac = jax.jacfwd(lambda p: eqx.combine(p, static).magnitude(v))(params)
    for name in ("Fs", "Fc", "Vs", "delta"):
        assert np.all(np.isfinite(np.asarray(getattr(jac, name)))), name
    grads = jax.grad(lambda p: jnp.sum(eqx.combine(p, static).magnitude(v)))(params)
    assert all(np.isfinite(float(g)) for g in jax.tree.leaves(grads))
    mag = np.asarray(STEEP.magnitude(v))
    assert mag[0] == 24.0 and np.all(mag[-3:] == 22.0)


@pytest.mark.parametrize("delta", [0.6, 1.0, 2.0, 40.0])
def test_magnitude_values_are_the_formula(delta):
    s = jaxfric.Stribeck(Fs=3.0, Fc=2.0, Vs=0.01, delta=delta)
    v = np.linspace(-0.05, 0.05, 101)
    want = 2.0 + np.exp(-((np.abs(v) / 0.01) ** delta))
    np.testing.assert_allclose(np.asarray(s.magnitude(v)), want, rtol=1e-14)


@pytest.mark.parametrize("mode", ["kernel", "jax"])
def test_two_state_jacobian_is_finite_with_a_steep_curve(mode, monkeypatch):
    if mode == "kernel" and _kernel.find_compiler() is None:
        pytest.skip("no C++ compiler on this machine")
    t = np.linspace(0.0, 4.0, 801)
    x = 0.02 * np.sin(2 * np.pi * 0.5 * t)  # peak speed 0.063 m/s, 12 Vs
    model = eqx.tree_at(lambda m: m.stribeck, paper.two_state(), STEEP)
    params, static = eqx.partition(model, eqx.is_inexact_array)
    monkeypatch.setenv(_kernel.ENV, mode)
    jax.clear_caches()
    jac = jax.jacfwd(lambda p: jaxfric.simulate(eqx.combine(p, static), t, x))(params)
    for path, leaf in jax.tree_util.tree_leaves_with_path(jac):
        assert np.all(np.isfinite(np.asarray(leaf))), jax.tree_util.keystr(path)
