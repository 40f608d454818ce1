"""The N-element GMS's element recursion as a compiled CPU kernel (`jaxfric._kernel.gms`)
against the JAX scan (`GMS._element_forces`): forces and every column of the Jacobian to
rounding, on motions with dwells, dense reversals and a standstill at the start, with a
Stribeck hump and with a static level below the Coulomb level (the elements' cap then
follows Fc); under ``vmap`` over parameter sets; through `jaxfric.simulate`."""

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import _kernel, trajectories
from jaxfric._models import gms


pytestmark = pytest.mark.skipif(_kernel.find_compiler() is None,
                                reason="no C++ compiler on this machine")

RTOL = 1e-12  # libm's exp and XLA's differ in the last bits


def _motion(kind):
    t = np.arange(0.0, 3.0, 2e-3)
    if kind == "moves":  # moves, dwells, reversals
        x = trajectories.point_to_point(t, np.random.default_rng(3))
    else:  # a rest, then a dithered sine: a reversal every few samples
        rng = np.random.default_rng(5)
        x = 2e-5 * np.sin(2 * np.pi * 1.3 * t) * (t > 0.2) + 3e-7 * rng.standard_normal(t.size)
    return jaxfric.motion.make_motion(jnp.asarray(t), jnp.asarray(x),
                                      jnp.asarray(np.gradient(x, t))).consistent()


def _model(Fs):
    stribeck = jaxfric.Stribeck(Fs=Fs, Fc=22.0, Vs=4e-3, delta=2.0)
    return jaxfric.GMS.from_shape(jaxfric.PowerShape(l1=4e-6, n=2.5), stribeck, 80.0, 15.0, 7)


def _run(mode, fn):
    with _kernel.forced(mode):
        return fn()


def _jac(model, motion):
    params, static = eqx.partition(model, eqx.is_inexact_array)
    y, unravel = jax.flatten_util.ravel_pytree(params)
    def f(p):
        return gms._elements(eqx.combine(unravel(p), static), motion)

    return f(y), jax.jacfwd(f)(y)


@pytest.mark.parametrize("kind", ["moves", "dither"])
@pytest.mark.parametrize("Fs", [30.0, 15.0])  # 15 < Fc: the cap factor is Fc
def test_forces_and_jacobian_are_the_scans(kind, Fs):
    model, motion = _model(Fs), _motion(kind)
    # a new function per mode: a compiled program keeps the path it was traced with
    f_k, j_k = _run("kernel", lambda: jax.jit(lambda m, mo: _jac(m, mo))(model, motion))
    f_j, j_j = _run("jax", lambda: jax.jit(lambda m, mo: _jac(m, mo))(model, motion))
    plain = jnp.sum(model._element_forces(motion), axis=-1)
    np.testing.assert_allclose(f_j, plain, rtol=RTOL, atol=1e-12)
    scale = float(jnp.abs(f_j).max())
    np.testing.assert_allclose(f_k, f_j, rtol=RTOL, atol=RTOL * scale)
    assert np.all(np.isfinite(j_k))
    np.testing.assert_allclose(j_k, j_j, rtol=1e-10,
                               atol=1e-12 * float(jnp.abs(j_j).max()))


def test_the_kernel_runs_where_it_applies():
    model, motion = _model(30.0), _motion("moves")
    jaxpr = _run("kernel", lambda: str(jax.make_jaxpr(lambda m: jax.jacfwd(
        lambda c: gms._elements(eqx.tree_at(lambda g: g.C, m, c), motion))(m.C))(model)))
    assert "jaxfric_gms_jacobian" in jaxpr
    assert "jaxfric_gms" not in _run("jax", lambda: str(jax.make_jaxpr(
        lambda m: gms._elements(m, motion))(model)))


def test_under_vmap_and_through_simulate():
    motion = _motion("moves")
    models = jax.vmap(lambda c: eqx.tree_at(lambda m: m.C, _model(30.0), c))(
        jnp.array([5.0, 15.0, 60.0]))
    batched = _run("kernel", lambda: jax.vmap(lambda m: gms._elements(m, motion))(models))
    for i in range(3):
        one = jax.tree.map(lambda a, i=i: a[i] if eqx.is_array(a) and a.ndim else a, models)
        np.testing.assert_allclose(batched[i], jnp.sum(one._element_forces(motion), -1),
                                   rtol=RTOL, atol=1e-12)
    model = _model(30.0)
    t, x = np.asarray(motion.t), np.asarray(motion.x)
    np.testing.assert_allclose(_run("kernel", lambda: jaxfric.simulate(model, t, x)),
                               _run("jax", lambda: jaxfric.simulate(model, t, x)),
                               rtol=RTOL, atol=1e-12)
