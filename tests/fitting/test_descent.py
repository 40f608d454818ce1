"""The damped Gauss-Newton step from one QR decomposition per point
(`fitting._descent.QRDampedNewtonDescent`) is optimistix's ``DampedNewtonDescent`` with
``lx.QR``: the same step for every damping, with a pytree of parameters, a rank-deficient
Jacobian (a held coordinate's zero column) and another right-hand side (`with_residual`,
the geodesic acceleration's)."""

import jax
import jax.flatten_util
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
import pytest

from fitting._descent import QRDampedNewtonDescent


def _f_info(jac, resid, y):
    """`f_info` of a residual linear in the pytree `y` with Jacobian `jac` (n x p)."""
    op = lx.FunctionLinearOperator(lambda t: jac @ jax.flatten_util.ravel_pytree(t)[0],
                                   jax.eval_shape(lambda: y))
    return optx.FunctionInfo.ResidualJac(resid, lx.materialise(op))


@pytest.mark.parametrize("held", [False, True])
def test_the_step_is_optimistix_damped_newton_step(held):
    rng = np.random.default_rng(0)
    n, y = 200, {"a": jnp.zeros(3), "b": jnp.zeros(())}
    jac = rng.standard_normal((n, 4)) * np.array([1.0, 1e3, 1e-4, 10.0])  # badly scaled
    if held:
        jac[:, 2] = 0.0
    jac, resid, other = map(jnp.asarray, (jac, rng.standard_normal(n), rng.standard_normal(n)))
    info = _f_info(jac, resid, y)
    ours, ref = QRDampedNewtonDescent(), optx.DampedNewtonDescent(linear_solver=lx.QR())
    s_ours = ours.query(y, info, ours.init(y, jax.eval_shape(lambda: info)))
    s_ref = ref.query(y, info, ref.init(y, info))
    s_other = ours.with_residual(s_ours, other)
    s_other_ref = ref.query(y, optx.FunctionInfo.ResidualJac(other, info.jac), s_ref)
    for step_size in (1e-12, 1e-6, 1e-2, 1.0, 1e4, 1e12, 0.0):
        step_size = jnp.asarray(step_size)
        for mine, theirs in ((s_ours, s_ref), (s_other, s_other_ref)):
            a, ra = ours.step(step_size, mine)
            b, rb = ref.step(step_size, theirs)
            assert ra == rb == optx.RESULTS.successful
            a, b = jax.flatten_util.ravel_pytree(a)[0], jax.flatten_util.ravel_pytree(b)[0]
            assert np.all(np.isfinite(a))
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * float(jnp.abs(b).max()))
            if held:
                assert a[2] == 0.0  # nothing moves a coordinate the residual does not see
