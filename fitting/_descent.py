"""The damped Gauss-Newton step of the fits (`fitting._geodesic`), from one QR
decomposition of the Jacobian per accepted point.

``optx.DampedNewtonDescent`` with ``lx.QR`` solves the damped least-squares problem

    min_d |J d - r|^2 + lambda |d|^2,    lambda = 1 / step_size,

by decomposing the stacked ``(n + p) x p`` matrix ``[J; sqrt(lambda) I]`` at every call:
once per step, once more for the geodesic acceleration (the same ``J`` and ``lambda``,
another right-hand side), again after each rejected step (a new ``lambda``, the same
``J``). With ``J = Q R`` (thin QR, decomposed once where the point is accepted),
``|J d - r|^2 = |R d - Q^T r|^2 + |r - Q Q^T r|^2``, and the second term does not
depend on ``d``: the same minimiser comes from the ``2p x p`` problem

    min_d |R d - Q^T r|^2 + lambda |d|^2,

whose decomposition costs ``O(p^3)`` instead of ``O(n p^2)`` (MINPACK's ``lmpar`` works on
``R`` the same way). A right-hand side of its own (the acceleration's ``r_vv``) needs
only ``Q^T r_vv`` (`with_residual`). Mathematically the step of
``optx.DampedNewtonDescent``; numerically as stable (orthogonal factorisations only,
never ``J^T J``); equal to it to rounding (tests/fitting/test_descent.py).
"""

import math

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import lineax as lx
import optimistix as optx
from jaxtyping import Array


class QRState(eqx.Module):
    """The point's `f_info` (as ``optx.DampedNewtonDescent``'s state) and the thin QR
    factors of its Jacobian, ``q`` (n x p) and ``r`` (p x p), with ``qtr = Q^T r``."""

    f_info: optx.FunctionInfo.ResidualJac
    q: Array
    r: Array
    qtr: Array


def _flat(tree) -> Array:
    return jax.flatten_util.ravel_pytree(tree)[0]


def _size(structure) -> int:
    return sum(math.prod(s.shape) for s in jax.tree.leaves(structure))


class QRDampedNewtonDescent(optx.AbstractDescent):
    """Levenberg-Marquardt's damped Gauss-Newton step (as ``optx.DampedNewtonDescent``,
    for least-squares problems), the Jacobian decomposed once per accepted point (module
    docstring). `query` needs the Jacobian as a matrix (materialised)."""

    def init(self, y, f_info_struct) -> QRState:
        n = _size(f_info_struct.residual)
        p = _size(f_info_struct.jac.in_structure())
        f_info = jax.tree.map(
            lambda s: jnp.zeros(s.shape, s.dtype) if isinstance(s, jax.ShapeDtypeStruct)
            else s, f_info_struct, is_leaf=lambda s: isinstance(s, jax.ShapeDtypeStruct))
        dtype = _flat(y).dtype
        return QRState(f_info=f_info, q=jnp.zeros((n, p), dtype), r=jnp.zeros((p, p), dtype),
                      qtr=jnp.zeros((p,), dtype))

    def query(self, y, f_info, state: QRState) -> QRState:
        del y, state
        q, r = jnp.linalg.qr(f_info.jac.as_matrix(), mode="reduced")
        return QRState(f_info=f_info, q=q, r=r, qtr=q.T @ _flat(f_info.residual))

    def with_residual(self, state: QRState, residual) -> QRState:
        """`state` with another right-hand side (the same Jacobian and factors)."""
        return QRState(f_info=optx.FunctionInfo.ResidualJac(residual, state.f_info.jac),
                      q=state.q, r=state.r, qtr=state.q.T @ _flat(residual))

    def step(self, step_size, state: QRState):
        # optimistix's damped_newton_step: lambda = 1 / step_size, the largest float for a
        # step size at or below the machine epsilon (no step)
        pred = step_size > jnp.finfo(step_size.dtype).eps
        lm = jnp.where(pred, 1.0 / jnp.where(pred, step_size, 1.0),
                       jnp.finfo(step_size.dtype).max)
        p = state.r.shape[0]
        a = jnp.concatenate([state.r, jnp.sqrt(lm) * jnp.eye(p, dtype=state.r.dtype)])
        b = jnp.concatenate([state.qtr, jnp.zeros_like(state.qtr)])
        sol = lx.linear_solve(lx.MatrixLinearOperator(a), b, lx.QR(), throw=False)
        unravel = jax.flatten_util.ravel_pytree(
            jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype),
                         state.f_info.jac.in_structure()))[1]
        return unravel(-sol.value), optx.RESULTS.promote(sol.result)
