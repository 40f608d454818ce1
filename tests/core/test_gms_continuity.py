"""The GMS force is continuous in its parameters (docs/algorithm.md section 5, step 3): an
element that meets its limit within a sample slips from there, so a start that moves
across a sample boundary does not make the force jump. (Slipping from the sample's end,
the force jumped by 0.5 N at some Stribeck parameters on point-to-point moves, for
0.1 % changes of them, and fits stopped at those jumps.)"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import trajectories


@pytest.mark.parametrize("name,get,lo,hi", [
    ("Vs", lambda m: m.stribeck.Vs, 4e-3, 4.4e-3),
    ("Fs", lambda m: m.stribeck.Fs, 30.0, 31.0),
])
def test_gms_force_has_no_jump_along_a_stribeck_parameter(name, get, lo, hi):
    t = np.arange(0.0, 6.0, 2e-3)  # point-to-point moves: short strong accelerations
    x = trajectories.point_to_point(t, np.random.default_rng(0))
    v = np.gradient(x, t)
    stribeck = jaxfric.Stribeck(Fs=30.0, Fc=22.0, Vs=4e-3, delta=2.0)
    model = jaxfric.GMS.from_shape(jaxfric.PowerShape(l1=4e-6, n=2.5), stribeck, 80.0,
                                   15.0, 20)
    values = jnp.linspace(lo, hi, 1001)
    forces = jax.jit(jax.vmap(lambda p: jaxfric.simulate(eqx.tree_at(get, model, p),
                                                         t, x, v)))(values)
    change = np.abs(np.diff(np.asarray(forces), axis=0)).max(axis=1)  # N, per grid step
    # Smooth: every grid step changes the force by about as much as the typical one.
    assert change.max() < 3.0 * np.median(change), f"{name}: a jump of {change.max():.3g} N"
