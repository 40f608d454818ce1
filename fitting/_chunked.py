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
  ``atol + rtol*|value|``); the cost fell by less than `ftol` (relative) over the last
  `CHUNK` steps or more; those steps changed the prediction by less than `xtol` of the
  residual's norm; every column of the Jacobian is nearly orthogonal to the residual
  (MINPACK's ``gtol``: the largest cosine below `gtol`); the Gauss-Newton step still left
  is shorter than `setol` standard errors (the statistician's test: what is left is far
  below the noise, however slowly the solver would creep there). The look-back is counted in steps,
  not calls, so the decision does not depend on how fast the machine runs.
- *Trust region*: each call starts from the previous call's trust-region size (its
  Levenberg-Marquardt damping), not from the initial one.
- `max_steps` and the tolerances are plain Python values here and traced values in the
  compiled chunk (the last chunk's step budget is an array, `_Budgeted`): changing them does
  not recompile, and a second fit of the same shapes reuses the compiled chunk.
- Chunk sizes are fixed (`MIN_CHUNK` steps for the first call, which also compiles, then
  `CHUNK`), not chosen from the measured time per step: the scaling is renewed and the
  solver restarted at chunk boundaries, so boundaries that moved with the machine's load
  made the same fit land on different optima from run to run (seen on the EMPS record:
  different effects added by a diagnosis). Ctrl-C: Python handles the signal between
  chunks (a chunk of 1e5 samples lasts a few seconds on two cores); the command line
  stops within a second whatever runs (`fitting.cli._interrupt`).
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

from jaxfric._compile import jit

from ._data import Dataset
from ._problem import _force_scale, _Problem, _residuals
from ._result import status_name
from ._solve import _Core, _evaluate_impl, _finish_impl, STUCK_COSINE


#: Most solver steps per compiled call (static: the loop bound of `_chunk`).
CHUNK = 32
#: Fewest steps per call (the first step of a call only evaluates the residual at its start).
MIN_CHUNK = 8


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """When a fit is done (any one rule; see the module docstring).

    - `ftol`: relative decrease of the cost ``sum(r^2)/2`` over the last chunk of steps;
    - `xtol`: change of the prediction by the last chunk's steps, linearised
      (``|J dy|``), relative to the norm of the residual;
    - `gtol`: largest cosine between a Jacobian column and the residual;
    - `setol`: length, in standard errors, of the Gauss-Newton step still left (``sqrt(z2)``,
      ``z2 = |J dy|^2 / s^2``: the cost a full step could still remove, in units of the
      noise variance ``s^2 = RSS/n``). Below 0.1 the parameters are settled to a tenth of
      their uncertainty: further steps only creep along weakly determined directions.
    """

    ftol: float = 1e-6
    xtol: float = 1e-6
    gtol: float = 1e-8
    setol: float = 0.1


class _Budgeted(optx.AbstractLeastSquaresSolver):
    """`solver` that also stops after `budget` steps, and whose trust region (for a
    solver with one, e.g. Levenberg-Marquardt) starts at `step_size` when it is > 0: the
    previous chunk's, so that a chunk goes on where the last one stopped instead of
    starting again from the initial damping. Both are arrays: new values do not
    recompile."""

    solver: Any
    budget: Array
    step_size: Array

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
        if hasattr(inner, "search_state") and hasattr(inner.search_state, "step_size"):
            size = inner.search_state.step_size
            inner = eqx.tree_at(lambda s: s.search_state.step_size, inner,
                                jnp.where(self.step_size > 0, self.step_size, size))
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
    step_size: Array  # the trust region's at the end (0 for a solver without one)


def _scaled_residuals(z, args):
    problem, data, scale, y_c, inv_d = args
    return _residuals(y_c + inv_d * z, (problem, data, scale))


@jit
def _chunk(problem: _Problem, y_c, inv_d, data: Dataset, solver, budget,
           step_size) -> _ChunkOut:
    """At most ``min(budget, CHUNK)`` solver steps from `y_c` in the coordinates
    ``z = (y - y_c) / inv_d``; residuals and Jacobian at the last accepted point are taken
    from the solver's state (see `fitting._solve._solve_impl` for why)."""
    args = (problem, data, _force_scale(data), y_c, inv_d)
    sol = optx.least_squares(_scaled_residuals, _Budgeted(solver, budget, step_size),
                             jnp.zeros_like(y_c), args, has_aux=True, max_steps=CHUNK,
                             throw=False)
    inner = sol.state[0]
    force, overflow = inner.aux
    search = getattr(inner, "search_state", None)
    size = getattr(search, "step_size", jnp.zeros(()))
    return _ChunkOut(y=y_c + inv_d * sol.value, result=sol.result,
                     num_steps=sol.stats["num_steps"], resid=inner.f_info.residual.ravel(),
                     jac=inner.f_info.jac.as_matrix() / inv_d, force=force,
                     overflow=overflow, step_size=jnp.asarray(size, y_c.dtype))


_evaluate = jit(_evaluate_impl)
_finish = jit(_finish_impl)


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




def _stop_reason(out: _ChunkOut, budget: int, cost: float, ref: tuple, tol: Tolerances,
                 mask, n_obs: int):
    """``(why, converged)`` after this chunk, ``why`` in words, or ``(None, False)`` to go
    on. `ref` is ``(steps, cost, y)`` of the fit at least `CHUNK` steps before (or at its
    start): the cost and step rules look back that far whatever the chunks' sizes, so the
    decision does not depend on how fast the machine ran them."""
    if int(out.num_steps) < budget:
        return "the solver's own test (last step and residual change within rtol/atol)", True
    ref_steps, ref_cost, ref_y = ref
    window = f"the last {ref_steps} steps"
    if np.isfinite(ref_cost) and ref_cost - cost <= 0:
        cosine = _max_cosine(out.jac, out.resid)
        if cosine <= STUCK_COSINE:
            return (f"no step lowers the cost, and the gradient is nil (cosine "
                    f"{cosine:.1e}): at the optimum", True)
        return (f"no step lowers the cost although the gradient is not nil (cosine "
                f"{cosine:.1e}): the fit is stuck", False)
    if np.isfinite(ref_cost) and ref_cost - cost <= tol.ftol * ref_cost:
        return f"the cost fell by less than ftol = {tol.ftol:g} (relative) over {window}", True
    resid = np.asarray(out.resid)
    moved = float(np.linalg.norm(np.asarray(out.jac) @ (np.asarray(out.y) - np.asarray(ref_y))))
    if moved <= tol.xtol * float(np.linalg.norm(resid)):
        return (f"{window} changed the prediction by less than xtol = {tol.xtol:g} of the "
                "residual", True)
    if _max_cosine(out.jac, resid) <= tol.gtol:
        return f"the gradient is below gtol = {tol.gtol:g} (cosine test)", True
    left = _step_left(out.jac, resid, mask, n_obs)
    if left <= tol.setol:
        return (f"the Gauss-Newton step left is {left:.2g} standard errors (setol = "
                f"{tol.setol:g}): the parameters are settled", True)
    return None, False


def _step_left(jac, resid, mask, n_obs: int) -> float:
    """`fitting._solve._remaining_step` in NumPy: the length, in standard errors, of the
    Gauss-Newton step left at this point (free coordinates `mask`)."""
    jf = np.asarray(jac)[:, np.asarray(mask) > 0]
    resid = np.asarray(resid)
    if jf.shape[1] == 0:
        return 0.0
    u, sv, _ = np.linalg.svd(jf, full_matrices=False)
    keep = sv > 1e-10 * sv.max() if sv.size and sv.max() > 0 else np.zeros(sv.shape, bool)
    projected = float(np.sum((u.T @ resid)[keep] ** 2))
    return float(np.sqrt(projected / max(float(np.sum(resid**2)) / n_obs, 1e-300)))


def _reference(history: list, steps: int) -> tuple:
    """The latest ``(steps, cost, y)`` of `history` at least `CHUNK` steps before `steps`
    (the oldest entry if none is), with its steps counted back from `steps`."""
    old = [h for h in history if h[0] <= steps - CHUNK] or history[:1]
    k, cost, y = old[-1]
    return steps - k, cost, y


def _next_budget(steps: int, max_steps: int) -> int:
    """Steps for the next call: `MIN_CHUNK` for the first (it also compiles, and the first
    progress report comes soon), `CHUNK` after, no more than `max_steps` allows. Fixed, so
    that the fit does not depend on the machine's speed (module docstring)."""
    return min(MIN_CHUNK if steps == 0 else CHUNK, max_steps - steps)


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
    y, steps = y0, 0
    mask = np.asarray(problem.layout.coordinate_mask())
    n_obs = int(np.sum(np.asarray(data.weights) > 0))
    d = np.zeros(np.shape(y0))
    step_size = jnp.zeros(())
    history = [(0, np.inf, np.asarray(y0))]  # (steps, cost, y) after each call
    result, reason, converged, out = optx.RESULTS.successful, None, False, None
    t0 = time.perf_counter()
    while steps < max_steps:
        budget = _next_budget(steps, max_steps)
        # Columns far weaker than the strongest are scaled as if 1e-3 of it: a nearly flat
        # column (a parameter saturating its bounded transform) would otherwise get steps so
        # long that they push it further into its bound.
        floor = 1e-3 * d.max() if d.max() > 0 else 0.0
        inv_d = jnp.asarray(1.0 / np.where(d > 0, np.maximum(d, floor), 1.0))
        out = _chunk(problem, y, inv_d, data, solver, jnp.asarray(budget, jnp.int32),
                     step_size)
        taken = int(out.num_steps)
        steps += taken
        result = out.result
        cost = 0.5 * float(np.sum(np.asarray(out.resid) ** 2))
        if result != optx.RESULTS.successful or not np.isfinite(cost):
            why = status_name(result) if np.isfinite(cost) else "non-finite cost"
            reason, y = f"the solver stopped ({why})", out.y
            break
        # (The start's cost is not evaluated: inf, so the cost rules wait for a reference.)
        reason, converged = _stop_reason(out, budget, cost, _reference(history, steps), tol,
                                         mask, n_obs)
        y, step_size = out.y, out.step_size
        history.append((steps, cost, np.asarray(y)))
        d = np.maximum(d, _column_norms(out.jac))
        if progress is not None:
            progress(_Progress(steps, cost, time.perf_counter() - t0))
        if reason is not None:
            break
    if reason is None:
        result, reason = (optx.RESULTS.nonlinear_max_steps_reached,
                          f"max_steps = {max_steps} reached")
    elif result == optx.RESULTS.successful and not converged:
        result = optx.RESULTS.nonlinear_divergence
    core = _finish(problem, y, data, out.resid, out.jac, out.force, out.overflow, result,
                   jnp.asarray(steps))
    return core, reason
