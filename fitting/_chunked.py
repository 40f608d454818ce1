"""A fit that stops when it is done: the optimistix solver run in short compiled chunks, with
Marquardt's column scaling renewed between them and stopping rules a user can read.

**Chunks.** `fit` runs the least-squares solver for at most `CHUNK` steps per compiled call
(`_chunk`), then decides in Python whether to go on. Between chunks:

- *Scaling* (Marquardt 1963; MINPACK's ``diag``): the solver works on ``z`` with
  ``y = y_c + d^-1 * z``, where ``d`` holds the norms of the Jacobian's columns (the largest
  seen so far, as MINPACK keeps them). In those coordinates every column has unit norm, so
  the Levenberg-Marquardt damping ``lambda*I`` acts like Marquardt's ``lambda*diag(J^T J)``
  and the damped steps are well conditioned whatever the parameters' units. Without it, a
  two-state fit to 1e4 samples of a foreign truth crept along a badly scaled valley for 300
  steps and stopped 19 % above the RMSE the scaled solve reached in about 100.
- *Stopping rules* (`Tolerances`, documented defaults), any one of which ends the fit as
  converged: optimistix's own test (last step and change of every residual below
  ``atol + rtol*|value|``); the cost fell by less than `ftol` (relative) over the last chunk;
  the Gauss-Newton step the chunk took changed the prediction by less than `xtol` of the
  residual's norm; every column of the Jacobian is nearly orthogonal to the residual
  (MINPACK's ``gtol``: the largest cosine below `gtol`).
- `max_steps` and the tolerances are plain Python values here and traced values in the
  compiled chunk (the last chunk's step budget is an array, `_Budgeted`): changing them does
  not recompile, and a second fit of the same shapes reuses the compiled chunk.
- Ctrl-C: Python handles the signal between chunks. Each chunk's budget is chosen from the
  measured time per step so that a call lasts about `CHUNK_SECONDS` (at most `CHUNK`
  steps), so an interrupted fit stops within a second or two.
"""

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array

from ._data import Dataset
from ._problem import _force_scale, _Problem, _residuals
from ._solve import _Core, _evaluate_impl, _finish_impl


#: Most solver steps per compiled call (static: the loop bound of `_chunk`).
CHUNK = 32
#: Fewest steps per call (the first step of a call only evaluates the residual at its start).
MIN_CHUNK = 4
#: Target duration of one compiled call (s): the latency of Ctrl-C and of progress reports.
CHUNK_SECONDS = 1.0


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """When a fit is done (any one rule; see the module docstring).

    - `ftol`: relative decrease of the cost ``sum(r^2)/2`` over the last chunk of steps;
    - `xtol`: change of the prediction by the last chunk's steps, linearised
      (``|J dy|``), relative to the norm of the residual;
    - `gtol`: largest cosine between a Jacobian column and the residual.
    """

    ftol: float = 1e-6
    xtol: float = 1e-6
    gtol: float = 1e-8


class _Budgeted(optx.AbstractLeastSquaresSolver):
    """`solver` that also stops after `budget` steps (an array: a new value does not
    recompile). Each chunk starts from the solver's initial damping: carrying the trust
    region over made no measurable difference in steps and cost a second compilation (the
    first call's state structure differs)."""

    solver: Any
    budget: Array

    @property
    def rtol(self):
        return self.solver.rtol

    @property
    def atol(self):
        return self.solver.atol

    @property
    def norm(self):
        return self.solver.norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        inner = self.solver.init(fn, y, args, options, f_struct, aux_struct, tags)
        return inner, jnp.zeros((), jnp.int32)

    def step(self, fn, y, args, options, state, tags):
        inner, count = state
        y, inner, aux = self.solver.step(fn, y, args, options, inner, tags)
        return y, (inner, count + 1), aux

    def terminate(self, fn, y, args, options, state, tags):
        inner, count = state
        done, result = self.solver.terminate(fn, y, args, options, inner, tags)
        return done | (count >= self.budget), result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return self.solver.postprocess(fn, y, aux, args, options, state[0], tags, result)


class _ChunkOut(eqx.Module):
    y: Array
    result: optx.RESULTS
    num_steps: Array
    resid: Array
    jac: Array  # d resid / d y (not z)
    force: Array
    overflow: Array


def _scaled_residuals(z, args):
    problem, data, scale, y_c, inv_d = args
    return _residuals(y_c + inv_d * z, (problem, data, scale))


@eqx.filter_jit
def _chunk(problem: _Problem, y_c, inv_d, data: Dataset, solver, budget) -> _ChunkOut:
    """At most ``min(budget, CHUNK)`` solver steps from `y_c` in the coordinates
    ``z = (y - y_c) / inv_d``; residuals and Jacobian at the last accepted point are taken
    from the solver's state (see `fitting._solve._solve_impl` for why)."""
    args = (problem, data, _force_scale(data), y_c, inv_d)
    sol = optx.least_squares(_scaled_residuals, _Budgeted(solver, budget), jnp.zeros_like(y_c),
                             args, has_aux=True, max_steps=CHUNK, throw=False)
    inner = sol.state[0]
    force, overflow = inner.aux
    return _ChunkOut(y=y_c + inv_d * sol.value, result=sol.result,
                     num_steps=sol.stats["num_steps"], resid=inner.f_info.residual.ravel(),
                     jac=inner.f_info.jac.as_matrix() / inv_d, force=force,
                     overflow=overflow)


_evaluate = eqx.filter_jit(_evaluate_impl)
_finish = eqx.filter_jit(_finish_impl)


def _column_norms(jac) -> np.ndarray:
    return np.linalg.norm(np.asarray(jac), axis=0)


def _max_cosine(jac, resid) -> float:
    """MINPACK's gradient test: the largest ``|J_i . r| / (|J_i| |r|)``."""
    jac, resid = np.asarray(jac), np.asarray(resid)
    norms = _column_norms(jac)
    rn = float(np.linalg.norm(resid))
    keep = norms > 0
    if rn == 0 or not keep.any():
        return 0.0
    return float(np.max(np.abs(jac[:, keep].T @ resid) / (norms[keep] * rn)))


@dataclasses.dataclass
class _Progress:
    """Where a chunked solve stands (passed to a `progress` callback after each chunk)."""

    steps: int
    cost: float
    seconds: float


#: A fit none of whose steps lowers the cost is at its optimum if the largest cosine between
#: a Jacobian column and the residual is at most this; otherwise it is stuck.
STUCK_COSINE = 1e-4


def _stop_reason(out: _ChunkOut, budget: int, cost0: float, cost: float, y_prev,
                 tol: Tolerances):
    """``(why, converged)`` after this chunk, ``why`` in words, or ``(None, False)`` to go
    on."""
    if int(out.num_steps) < budget:
        return "the solver's own test (last step and residual change within rtol/atol)", True
    if np.isfinite(cost0) and cost0 - cost <= 0:
        if budget < CHUNK:  # a short chunk whose steps were all rejected: try a longer one
            return None, False
        cosine = _max_cosine(out.jac, out.resid)
        if cosine <= STUCK_COSINE:
            return (f"no step lowers the cost, and the gradient is nil (cosine "
                    f"{cosine:.1e}): at the optimum", True)
        return (f"no step lowers the cost although the gradient is not nil (cosine "
                f"{cosine:.1e}): the fit is stuck", False)
    if np.isfinite(cost0) and cost0 - cost <= tol.ftol * cost0:
        return (f"the cost fell by less than ftol = {tol.ftol:g} (relative) over the last "
                f"{int(out.num_steps)} steps", True)
    resid = np.asarray(out.resid)
    moved = float(np.linalg.norm(np.asarray(out.jac) @ (np.asarray(out.y) - np.asarray(y_prev))))
    if moved <= tol.xtol * float(np.linalg.norm(resid)):
        return f"the last steps changed the prediction by less than xtol = {tol.xtol:g}", True
    if _max_cosine(out.jac, resid) <= tol.gtol:
        return f"the gradient is below gtol = {tol.gtol:g} (cosine test)", True
    return None, False


def _next_budget(steps: int, max_steps: int, per_step: float | None) -> int:
    """Steps for the next call: about `CHUNK_SECONDS` of work (`MIN_CHUNK` until the time
    per step is known), `MIN_CHUNK` to `CHUNK`, no more than `max_steps` allows."""
    want = MIN_CHUNK if per_step is None else int(CHUNK_SECONDS / max(per_step, 1e-9))
    return min(max(MIN_CHUNK, min(CHUNK, want)), max_steps - steps)


def solve_chunked(problem: _Problem, y0, data: Dataset, solver, max_steps: int,
                  tol: Tolerances | None = None,
                  progress: Callable[[_Progress], None] | None = None) -> tuple[_Core, str]:
    """Solve in chunks (module docstring); returns the core arrays and why it stopped."""
    tol = Tolerances() if tol is None else tol
    if max_steps <= 0:
        resid, jac, force, overflow = _evaluate(problem, y0, data)
        core = _finish(problem, y0, data, resid, jac, force, overflow,
                       optx.RESULTS.nonlinear_max_steps_reached, jnp.asarray(0))
        return core, "max_steps = 0: no step taken"
    y, steps, per_step = y0, 0, None
    d = np.zeros(np.shape(y0))
    cost = np.inf
    result, reason, converged, out = optx.RESULTS.successful, None, False, None
    t0 = time.perf_counter()
    while steps < max_steps:
        budget = _next_budget(steps, max_steps, per_step)
        tick = time.perf_counter()
        inv_d = jnp.asarray(1.0 / np.where(d > 0, d, 1.0))
        out = _chunk(problem, y, inv_d, data, solver, jnp.asarray(budget, jnp.int32))
        taken = int(out.num_steps)
        steps += taken
        result = out.result
        new_cost = 0.5 * float(np.sum(np.asarray(out.resid) ** 2))
        if result != optx.RESULTS.successful or not np.isfinite(new_cost):
            reason, y = f"the solver stopped ({result})", out.y
            break
        reason, converged = _stop_reason(out, budget, cost, new_cost, y, tol)
        cost_before = cost
        y, cost = out.y, new_cost
        d = np.maximum(d, _column_norms(out.jac))
        if progress is not None:
            progress(_Progress(steps, cost, time.perf_counter() - t0))
        if reason is not None:
            break
        # Time per step measured from the second call on (the first also compiles).
        per_step = (time.perf_counter() - tick) / max(taken, 1) if steps > taken else None
        if np.isfinite(cost_before) and new_cost >= cost_before:
            # Every step rejected: a full chunk next, for the damping to grow (each call
            # starts from the solver's initial damping).
            per_step = 0.0
    if reason is None:
        result, reason = (optx.RESULTS.nonlinear_max_steps_reached,
                          f"max_steps = {max_steps} reached")
    elif result == optx.RESULTS.successful and not converged:
        result = optx.RESULTS.nonlinear_divergence
    core = _finish(problem, y, data, out.resid, out.jac, out.force, out.overflow, result,
                   jnp.asarray(steps))
    return core, reason
