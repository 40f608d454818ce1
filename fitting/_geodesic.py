"""Levenberg-Marquardt with geodesic acceleration (Transtrum and Sethna 2012, "Improvements
to the Levenberg-Marquardt algorithm for nonlinear least-squares minimization").

In a curved valley of the cost (the presliding shape's quartic ~ l1, LuGre's bristles,
Fc ~ Vs) the damped Gauss-Newton step ``v`` leaves the valley's floor: what a long step
gains falls short of the linear prediction, the trust region stays small, and the fit
crawls along the valley at a fixed fraction of what is left per step. Geodesic
acceleration adds the second-order correction of the path the prediction moves along:
with ``r_vv``, the second directional derivative of the residual along ``v`` (a finite
difference over `FD_STEP` of ``v``: one residual evaluation per step, against the
``p + 1`` of the residual and Jacobian),

    a = -(J^T J + lambda I)^-1 J^T r_vv,    step = v + a / 2,

used when ``2 |a| <= ACCEL_RATIO * |v|`` (the correction is small against the step, so
the expansion holds), ``v`` alone otherwise. The trust region's ratio compares the cost
the step achieves with the decrease the linear model predicts for ``v``: the acceleration
is what makes the prediction come true along the curve. Everything else (the trust
region, its update, optimistix's own termination test, the damped step: `fitting._descent`
computes optimistix's from one QR decomposition per point) is as in
``optx.LevenbergMarquardt`` with `search`.
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx
from jaxtyping import Array, PyTree, Scalar

from ._descent import QRDampedNewtonDescent


#: The finite-difference step of ``r_vv``, as a fraction of ``v`` (Transtrum's 0.1).
FD_STEP = 0.1
#: The acceleration is used when ``2 |a| / |v|`` is at most this (Transtrum's 0.75).
ACCEL_RATIO = 0.75


class _State(eqx.Module):
    """optimistix's Gauss-Newton state (the same field names: `fitting._stopping` and
    `fitting._chunked` read `f_info`, `aux` and `search_state`) plus the acceleration."""

    first_step: Array
    y_eval: Any  # y + v: the point the trust region's prediction is for
    accel: Any  # a / 2 (zero when not used): the point evaluated is y_eval + accel
    search_state: Any
    f_info: Any
    aux: Any
    descent_state: Any
    terminate: Array
    result: optx.RESULTS


def _f_info(fn, y, args, tags):
    """The residual at `y` and its Jacobian (a linear operator), and the aux."""
    f, lin, aux = jax.linearize(lambda yy: fn(yy, args), y, has_aux=True)
    return optx.FunctionInfo.ResidualJac(
        f, lx.FunctionLinearOperator(lin, jax.eval_shape(lambda: y), tags)), aux


def _materialised(f_info):
    """`f_info` with its Jacobian as a matrix (``p`` tangent passes through the model,
    once): the damped solves, the trust region's prediction, the acceleration and the
    stopping rule (`fitting._stopping`) then multiply by it instead of each running the
    linearised simulation again."""
    return optx.FunctionInfo.ResidualJac(f_info.residual, lx.materialise(f_info.jac))


def _zeros(tree):
    """`tree` with each ``jax.ShapeDtypeStruct`` replaced by zeros (the rest kept)."""
    return jax.tree.map(
        lambda s: jnp.zeros(s.shape, s.dtype) if isinstance(s, jax.ShapeDtypeStruct) else s,
        tree, is_leaf=lambda s: isinstance(s, jax.ShapeDtypeStruct))


def _quiet(**kwargs) -> None:
    """No progress output (a module-level function: a fresh lambda per solver would make
    every fit's solver a new static argument, recompiling the chunk)."""


def _sum_squares(tree) -> Array:
    return sum(jnp.sum(leaf**2) for leaf in jax.tree.leaves(tree))


class GeodesicLevenbergMarquardt(optx.AbstractLeastSquaresSolver):
    """Levenberg-Marquardt (the damped Gauss-Newton step of `fitting._descent`, one QR
    decomposition of the Jacobian per accepted point; the trust region `search`) whose
    evaluated step adds half the geodesic acceleration (module docstring). `rtol`,
    `atol`, `norm`: optimistix's termination test, as for ``optx.LevenbergMarquardt``."""

    rtol: float
    atol: float
    norm: Callable[[PyTree], Scalar]
    search: optx.ClassicalTrustRegion
    descent: QRDampedNewtonDescent = QRDampedNewtonDescent()
    verbose: Callable[..., None] = _quiet
    accelerate: bool = eqx.field(static=True, default=True)

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        f_info_struct, _ = eqx.filter_eval_shape(
            lambda *a: (_materialised(_f_info(*a)[0]), None), fn, y, args, tags)
        return _State(
            first_step=jnp.array(True), y_eval=y, accel=jnp.zeros_like(y),
            search_state=self.search.init(y, f_info_struct), f_info=_zeros(f_info_struct),
            aux=_zeros(aux_struct),
            descent_state=self.descent.init(y, f_info_struct),
            terminate=jnp.array(False), result=optx.RESULTS.successful)

    def step(self, fn, y, args, options, state, tags):
        y_try = state.y_eval + state.accel
        f_eval_info, aux_eval = _f_info(fn, y_try, args, tags)
        # The ratio: the cost at y_try against the linear prediction for v (y_eval - y).
        step_size, accept, search_result, search_state = self.search.step(
            state.first_step, y, state.y_eval, state.f_info, f_eval_info,
            state.search_state)

        def accepted(descent_state):
            # (The Jacobian is materialised here only: a rejected step costs the
            # simulation and its linearisation, not the p tangent passes.)
            f_info = _materialised(f_eval_info)
            descent_state = self.descent.query(y_try, f_info, descent_state)
            f_diff = jax.tree.map(lambda a, b: a - b, f_eval_info.residual,
                                  state.f_info.residual)
            terminate = _cauchy(self.rtol, self.atol, self.norm, y_try, y_try - y,
                                f_eval_info.residual, f_diff)
            return y_try, f_info, aux_eval, descent_state, terminate

        def rejected(descent_state):
            return y, state.f_info, state.aux, descent_state, jnp.array(False)

        y, f_info, aux, descent_state, terminate = _filter_cond(
            accept, accepted, rejected, state.descent_state)
        v, descent_result = self.descent.step(step_size, descent_state)
        accel = (self._acceleration(fn, y, args, f_info, v, step_size, descent_state)
                 if self.accelerate else jnp.zeros_like(v))
        result = optx.RESULTS.where(search_result == optx.RESULTS.successful,
                                   descent_result, search_result)
        prev_aux = jax.tree.map(lambda a, b: jnp.where(state.first_step, a, b), aux,
                                state.aux)
        state = _State(first_step=jnp.array(False), y_eval=y + v, accel=accel,
                       search_state=search_state, f_info=f_info, aux=aux,
                       descent_state=descent_state, terminate=terminate, result=result)
        return y, state, prev_aux

    def _acceleration(self, fn, y, args, f_info, v, step_size, descent_state):
        """Half the geodesic acceleration along `v` from `y`, or zeros where it is not
        small against `v` (module docstring)."""
        r_h, _ = fn(y + FD_STEP * v, args)
        jv = f_info.jac.mv(v)
        rvv = jax.tree.map(lambda a, b, c: (2.0 / FD_STEP) * ((a - b) / FD_STEP - c),
                           r_h, f_info.residual, jv)
        accel, _ = self.descent.step(step_size, self.descent.with_residual(descent_state,
                                                                           rvv))
        size = jnp.linalg.norm(v)
        use = (2.0 * jnp.linalg.norm(accel) <= ACCEL_RATIO * size) & (size > 0) & jnp.all(
            jnp.isfinite(accel))
        return jnp.where(use, 0.5 * accel, 0.0)

    def terminate(self, fn, y, args, options, state, tags):
        return state.terminate, state.result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return y, aux, {}


def _filter_cond(pred, true_fun, false_fun, *operands):
    """``lax.cond`` over the arrays of `operands` and of the branches' outputs, the rest
    static (optimistix's own helper)."""
    dynamic, static = eqx.partition(operands, eqx.is_array)

    def branch(fun):
        def run(dyn):
            out = fun(*eqx.combine(dyn, static))
            dyn_out, static_out = eqx.partition(out, eqx.is_array)
            return dyn_out, eqxi.Static(static_out)
        return run

    dynamic_out, static_out = jax.lax.cond(pred, branch(true_fun), branch(false_fun),
                                           dynamic)
    return eqx.combine(dynamic_out, static_out.value)


def _cauchy(rtol, atol, norm, y, y_diff, f, f_diff):
    """optimistix's termination test: the step and every residual's change within
    ``atol + rtol*|value|``."""
    y_ok = norm(jnp.abs(y_diff) / (atol + rtol * jnp.abs(y))) < 1
    f_ok = norm(jax.tree.map(lambda d, v: jnp.abs(d) / (atol + rtol * jnp.abs(v)), f_diff,
                             f)) < 1
    return y_ok & f_ok
