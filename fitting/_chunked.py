"""A fit that stops when it is done: the optimistix solver run in short compiled chunks, with
Marquardt's column scaling renewed between them and stopping rules a user can read.

**Chunks.** `fit` runs the least-squares solver for at most `CHUNK` steps per compiled call
(`_chunk`), then decides in Python whether to go on. Between chunks:

- *Scaling* (Marquardt 1963; MINPACK's ``diag``): the solver works on ``z`` with
  ``y = y_c + d^-1 * z``, where ``d`` holds the norms of the Jacobian's columns (the largest
  seen so far, as MINPACK keeps them). In those coordinates every column has unit norm, so
  the Levenberg-Marquardt damping ``lambda*I`` acts like Marquardt's ``lambda*diag(J^T J)``
  and the damped steps are well conditioned whatever the parameters' units.
- *Stopping rules* (`Tolerances`, documented defaults), any one of which ends the fit as
  converged. Inside the compiled loop, after every step: the statistical rule of
  `fitting._stopping` (the Gauss-Newton decrease of the cost left over the directions the
  data determine is at most `decrease` noise variances; the steps stalled or settled,
  `_halted`), and optimistix's own test (last step and change of every residual below
  ``atol + rtol*|value|``). Between chunks: the
  cost fell by less than `ftol` (relative) over the last `CHUNK` steps or more; those
  steps changed the prediction by less than `xtol` of the residual's norm; every column of
  the Jacobian is nearly orthogonal to the residual (MINPACK's ``gtol``), for data without
  noise, where the noise variance is round-off. The look-back is counted in steps, not
  calls, so the decision does not depend on how fast the machine runs.
- *Undetermined parameters*: once a rule fires, a free scalar parameter whose standard
  error in the solver's coordinates exceeds `Tolerances.undetermined` (a factor e for a
  positive parameter) is held at its start and the others go on (`undetermined_leaves`);
  the result names it (`FitResult.undetermined`). The hold stands if that refit converges
  and passes a likelihood-ratio test against the fit before the hold (`_hold_accepted`);
  otherwise the fit before the hold is returned, the parameters named but not held.
- *Trust region*: each call, and the refit with undetermined parameters held, starts
  from the previous call's trust-region size (its Levenberg-Marquardt damping): a
  restart from the initial size spends steps regrowing the region.
- `max_steps` and the tolerances are plain Python values here and traced values in the
  compiled chunk (the last chunk's step budget is an array, `fitting._stopping.Stopping`):
  changing them does not recompile.
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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array
from scipy.special import gammaincinv

from jaxfric._compile import jit

from ._data import Dataset
from ._problem import _force_scale, _Problem, _residuals
from ._result import status_name
from ._solve import _Core, _evaluate_impl, _finish_impl, EXACT_RESIDUAL, MIN_R2, STUCK_COSINE
from ._stopping import decrease_left, STALL_PREDICTED, STALL_STEPS, Stopping, Tolerances
from ._transforms import Exp, Sigmoid, Softplus


#: Most solver steps per compiled call (static: the loop bound of `_chunk`).
CHUNK = 32
#: The confidence level of `_chance_bound`.
CONFIDENCE = 0.99
#: Fewest steps per call (the first step of a call only evaluates the residual at its start).
MIN_CHUNK = 8


class _ChunkOut(eqx.Module):
    y: Array
    result: optx.RESULTS
    num_steps: Array
    resid: Array
    jac: Array  # d resid / d y (not z)
    force: Array
    overflow: Array
    step_size: Array  # the trust region's at the end (0 for a solver without one)
    left: Array  # `decrease_left` at the end: the Gauss-Newton decrease left / s^2
    undetermined: Array  # how many free directions are undetermined there
    gained: Array  # the cost's decrease over the last `STALL_STEPS` steps / s^2 (or inf)
    moved: Array  # their move's squared length in standard errors (`Stopping.moved`)


def _scaled_residuals(z, args):
    problem, data, scale, y_c, inv_d = args
    return _residuals(y_c + inv_d * z, (problem, data, scale))


def _chunk_steps(problem: _Problem, y_c, inv_d, data: Dataset, solver, budget,
                 step_size, decrease, undetermined) -> _ChunkOut:
    """At most ``min(budget, CHUNK)`` solver steps from `y_c` in the coordinates
    ``z = (y - y_c) / inv_d``, each followed by the statistical rule (`Stopping`);
    residuals and Jacobian at the last accepted point are taken from the solver's state
    (see `fitting._solve._solve_impl` for why)."""
    args = (problem, data, _force_scale(data), y_c, inv_d)
    mask = problem.layout.coordinate_mask()
    n_obs = jnp.sum(data.weights > 0).astype(y_c.dtype)
    stopping = Stopping(solver, budget, step_size, decrease, undetermined, inv_d, mask,
                        n_obs)
    sol = optx.least_squares(_scaled_residuals, stopping, jnp.zeros_like(y_c), args,
                             has_aux=True, max_steps=CHUNK, throw=False)
    inner = sol.state[0]
    force, overflow = inner.aux
    search = getattr(inner, "search_state", None)
    size = getattr(search, "step_size", jnp.zeros(()))
    resid = inner.f_info.residual.ravel()
    jac = inner.f_info.jac.as_matrix() / inv_d
    left, count = decrease_left(jac, resid, mask, n_obs, undetermined)
    return _ChunkOut(y=y_c + inv_d * sol.value, result=sol.result,
                     num_steps=sol.stats["num_steps"], resid=resid, jac=jac, force=force,
                     overflow=overflow, step_size=jnp.asarray(size, y_c.dtype), left=left,
                     undetermined=count, gained=stopping.gained(sol.state, resid),
                     moved=stopping.moved(sol.state, inner.f_info.jac.as_matrix(), resid))


@jit
def _chunk(problem: _Problem, y_c, inv_d, data: Dataset, solver, budget, step_size,
           decrease, undetermined) -> _ChunkOut:
    """`_chunk_steps`, compiled (its name shows in JAX's logs and compilation cache)."""
    return _chunk_steps(problem, y_c, inv_d, data, solver, budget, step_size, decrease,
                        undetermined)
_evaluate = jit(_evaluate_impl)
_finish = jit(_finish_impl)


@jit
def _chunk_batch(problem: _Problem, y_c, inv_d, data: Dataset, solver, budget, step_size,
                 decrease, undetermined, vectorize=False) -> _ChunkOut:
    """`_chunk` for B datasets (a leading axis on `data` and on every other array but the
    tolerances): one after the other (`jax.lax.map`: a dataset whose budget is 0, being
    done, costs nothing) or vmapped (`vectorize`)."""
    def one(a):
        return _chunk_steps(problem, *a[:2], a[2], solver, a[3], a[4], decrease, undetermined)

    args = (y_c, inv_d, data, budget, step_size)
    return jax.vmap(one)(args) if vectorize else jax.lax.map(one, args)


@jit
def _finish_batch(problem: _Problem, y, data: Dataset, resid, jac, force, overflow, result,
                  num_steps) -> _Core:
    """`_finish` for B datasets (a leading axis on every argument but `problem`)."""
    return jax.vmap(lambda *a: _finish_impl(problem, *a))(y, data, resid, jac, force,
                                                         overflow, result, num_steps)


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




def _stop_reason(out: _ChunkOut, budget: int, cost: float, ref: tuple, tol: Tolerances):
    """``(why, kind)`` after this chunk, ``why`` in words and ``kind`` one of
    ``"converged"``, ``"kink"``, ``"stuck"`` (`fitting._result.STOPS`), or ``(None, None)``
    to go on. `ref` is ``(steps, cost, y)`` of the fit at least `CHUNK` steps before (or at its
    start): the cost and step rules look back that far whatever the chunks' sizes, so the
    decision does not depend on how fast the machine ran them."""
    left = float(out.left)
    if int(out.num_steps) < budget:
        if left <= tol.decrease:
            return (f"the Gauss-Newton decrease left is {left:.2g} noise variances "
                    f"(decrease = {tol.decrease:g}): nothing the data can tell is left",
                    "converged")
        bound = _chance_bound(out.jac)
        halted = _halted(out, left, bound, tol)
        if halted is not None:
            return halted
        gained = float(out.gained)
        ref_y = ref[2]
        exact = np.sqrt(np.mean(np.asarray(out.resid) ** 2)) <= EXACT_RESIDUAL
        cosine = _max_cosine(out.jac, out.resid)
        if np.array_equal(np.asarray(out.y), np.asarray(ref_y)) and not exact and (
                cosine > STUCK_COSINE):
            return (f"the solver's own test fired without moving the fit although the "
                    f"gradient is not nil (cosine {cosine:.1e}): the fit is stuck", "stuck")
        # The solver's own test (a step within rtol/atol) fires in a crawl as well as at
        # an optimum: it counts only where the fit is within a noise variance of where it
        # stands, by the linear model or by what the last steps achieved.
        if tol.decrease > 0 and not exact and (min(left, gained) > STALL_PREDICTED
                                               or left > bound):
            return (f"NOT converged: the solver's own test fired (last step within "
                    f"rtol/atol) before the fit settled: {left:.3g} noise variances "
                    f"predicted left, and the last steps still gaining "
                    f"({_gain_words(gained)})", "kink")
        return ("the solver's own test (last step and residual change within rtol/atol)",
                "converged")
    ref_steps, ref_cost, ref_y = ref
    window = f"the last {ref_steps} steps"
    if np.isfinite(ref_cost) and ref_cost - cost <= 0:
        cosine = _max_cosine(out.jac, out.resid)
        if cosine <= STUCK_COSINE:
            return (f"no step lowers the cost, and the gradient is nil (cosine "
                    f"{cosine:.1e}): at the optimum", "converged")
        return (f"no step lowers the cost although the gradient is not nil (cosine "
                f"{cosine:.1e}): the fit is stuck", "stuck")
    if np.isfinite(ref_cost) and ref_cost - cost <= tol.ftol * ref_cost:
        return (f"the cost fell by less than ftol = {tol.ftol:g} (relative) over {window}",
                "converged")
    resid = np.asarray(out.resid)
    moved = float(np.linalg.norm(np.asarray(out.jac) @ (np.asarray(out.y) - np.asarray(ref_y))))
    # (A window in which the fit has not moved says nothing: with max_steps=1 the only
    # step evaluates the start.)
    if moved <= tol.xtol * float(np.linalg.norm(resid)) and not np.array_equal(
            np.asarray(out.y), np.asarray(ref_y)):
        return (f"{window} changed the prediction by less than xtol = {tol.xtol:g} of the "
                "residual", "converged")
    if _max_cosine(out.jac, resid) <= tol.gtol:
        return f"the gradient is below gtol = {tol.gtol:g} (cosine test)", "converged"
    return None, None


def _halted(out: _ChunkOut, left: float, bound: float, tol: Tolerances):
    """``(why, kind)`` when the steps stalled (the cost) or settled (the estimates,
    `fitting._stopping`), else None: converged, or a kink where more decrease is left
    than chance allows (`bound`)."""
    if tol.decrease <= 0:
        return None
    gained, moved = float(out.gained), float(out.moved)
    if gained <= tol.decrease:
        why = (f"the steps stalled: the last {STALL_STEPS} gained under "
               f"{tol.decrease:g} noise variances, {left:.3g} predicted")
    elif moved <= 2.0 * tol.decrease:
        why = (f"the fit settled: the last {STALL_STEPS - 1} steps moved no linear "
               f"combination of the parameters by more than {np.sqrt(moved):.2g} of its "
               f"standard error, {left:.3g} noise variances predicted")
    else:
        return None
    if left <= bound:
        return why, "converged"
    return ("NOT converged: " + why + f", more than chance allows ({bound:.3g}): the "
            "linear model does not hold here (a kink of the cost) and the fit may be "
            "stuck", "kink")


def _chance_bound(jac) -> float:
    """The most decrease, in noise variances, that the Gauss-Newton step from a fit at its
    optimum leaves by chance: ``chi2.ppf(CONFIDENCE, p) / 2`` for the ``p`` free columns of
    `jac`. Twice the decrease left is the squared length of the step left in standard
    errors, which from the true parameters is chi-square with ``p`` degrees of freedom;
    a fit whose step left is longer stands outside the confidence region of the optimum
    its own linear model points to."""
    p = int(np.count_nonzero(np.linalg.norm(np.asarray(jac), axis=0) > 0))
    # chi2.ppf(q, k) = 2 gammaincinv(k / 2, q) (scipy.stats costs 0.5 s of every start)
    return float(gammaincinv(0.5 * max(p, 1), CONFIDENCE))


def _gain_words(gained: float) -> str:
    if not np.isfinite(gained):
        return f"fewer than {STALL_STEPS} steps in this call"
    return f"{gained:.3g} noise variances over the last {STALL_STEPS}"


_BOUNDED = (Exp, Softplus, Sigmoid)


def undetermined_leaves(jac, resid, layout, n_obs: int, limit: float,
                        pinned=()) -> list[int]:
    """Leaves to hold because the data do not determine them: while some free scalar leaf
    has a standard error above `limit` in the solver's coordinates (``s^2 (J^T J)^-1``
    over the free coordinates, ``s^2 = RSS/(n - p)``), the one with the largest is held
    and the others' errors are computed again (a pair the data fix only together then
    keeps one member free). Only scalar leaves on a log or logit scale are judged (`Exp`,
    `Softplus`, `Sigmoid`: there an error of 1 means not even a factor e, or a logit of 1);
    an `Identity` coordinate is scaled by its start, which says nothing of its precision
    when the value is near 0, and vector leaves (GMS weights and stiffnesses) are kept.
    Leaves `pinned` at a bound of their transform are not held either: their error is
    huge because the fit collapsed there, which the result reports as such."""
    jac, resid = np.asarray(jac), np.asarray(resid)
    leaf_of = layout.coordinate_leaf()
    free = np.asarray(layout.leaf_free).astype(bool).copy()
    scalar = np.array([size == 1 and shape == () and isinstance(tr, _BOUNDED)
                       and k not in pinned for k, (size, shape, tr) in
                       enumerate(zip(layout.sizes, layout.shapes, layout.transforms))])
    held: list[int] = []
    while True:
        cols = np.flatnonzero(free[leaf_of])
        if cols.size == 0:
            return held
        jf = jac[:, cols]
        norms = np.linalg.norm(jf, axis=0)
        norms = np.where(norms > 0, norms, 1.0)
        eig, vec = np.linalg.eigh((jf / norms).T @ (jf / norms))
        eig = np.maximum(eig, 1e-15 * max(float(eig.max()), 1e-300))
        with np.errstate(over="ignore"):  # an all-zero Jacobian: inf, undetermined
            var = ((vec**2) / eig).sum(axis=1) / norms**2
        s2 = float(np.sum(resid**2)) / max(n_obs - cols.size, 1)
        se = np.sqrt(s2 * var)
        leaves = leaf_of[cols]
        bad = [(se[k], leaves[k]) for k in range(cols.size)
               if scalar[leaves[k]] and not se[k] <= limit]
        if not bad:
            return held
        worst = max(bad)[1]
        held.append(int(worst))
        free[worst] = False


def _hold(problem: _Problem, leaves: list[int]) -> _Problem:
    """`problem` with `leaves` held at their values in its template (the start)."""
    flags = np.asarray(problem.layout.leaf_free).copy()
    flags[leaves] = False
    return eqx.tree_at(lambda p: p.layout.leaf_free, problem,
                       jnp.asarray(flags, dtype=problem.layout.leaf_free.dtype))


def _next_budget(steps: int, max_steps: int) -> int:
    """Steps for the next call: `MIN_CHUNK` for the first (it also compiles, and the first
    progress report comes soon), `CHUNK` after, no more than `max_steps` allows. Fixed, so
    that the fit does not depend on the machine's speed (module docstring)."""
    return min(MIN_CHUNK if steps == 0 else CHUNK, max_steps - steps)


def _reference(history: list, steps: int) -> tuple:
    """The latest ``(steps, cost, y)`` of `history` at least `CHUNK` steps before `steps`
    (the oldest entry if none is), with its steps counted back from `steps`."""
    old = [h for h in history if h[0] <= steps - CHUNK] or history[:1]
    k, cost, y = old[-1]
    return steps - k, cost, y


@dataclasses.dataclass
class Solved:
    """What `solve_chunked` returns: the core arrays, why it stopped, the problem as
    finally solved (with any undetermined leaves held), the names of those leaves and the
    kind of stop before `fit`'s checks (``"converged"``, ``"kink"``, ``"stuck"``,
    ``"max_steps"``, ``"failed"``: `fitting._result.final_stop`)."""

    core: _Core
    stopped: str
    problem: _Problem
    undetermined: tuple[str, ...] = ()
    stop: str = "failed"


def _run(problem: _Problem, y, d, data: Dataset, solver, budget: int, step_size,
         tol: Tolerances) -> _ChunkOut:
    """One chunk of at most `budget` steps from `y`, scaled by the column norms `d`."""
    inv_d = jnp.asarray(_inverse_scale(d))
    return _chunk(problem, y, inv_d, data, solver, jnp.asarray(budget, jnp.int32),
                  step_size, jnp.asarray(tol.decrease, float),
                  jnp.asarray(tol.undetermined, float))


@jit
def _at_bound(layout, y):
    """`Layout.at_bound` compiled (one program per layout's structure): op by op it costs
    tens of milliseconds per fit, a slice and a test per leaf."""
    return layout.at_bound(y)


def _inverse_scale(d: np.ndarray) -> np.ndarray:
    """``inv_d`` of the solver's coordinates from the column norms `d`."""
    # Columns far weaker than the strongest are scaled as if 1e-3 of it: a nearly flat
    # column (a parameter saturating its bounded transform) would otherwise get steps so
    # long that they push it further into its bound.
    floor = 1e-3 * d.max() if d.max() > 0 else 0.0
    return 1.0 / np.where(d > 0, np.maximum(d, floor), 1.0)


def _held_words(held: tuple[str, ...], loose: tuple[str, ...]) -> str:
    out = ""
    if held:
        out += f"; undetermined by the data, held at their start: {', '.join(held)}"
    if loose:
        out += (f"; large standard errors, not held (no steps left, or the fit with them "
                f"held at their start fits significantly worse): {', '.join(loose)}")
    return out


def _evaluate_at(problem: _Problem, y, data: Dataset, solver, tol: Tolerances):
    """Residuals, Jacobian (d resid / d y), force and overflow count at `y`: one step of the
    fit's own compiled chunk, which only evaluates its start (no other program to trace)."""
    zero = jnp.zeros(())  # a trust region's size as `solve_chunked` starts it (one program)
    out = _run(problem, jnp.asarray(y), np.zeros(np.shape(y)), data, solver, 1, zero, tol)
    return out.resid, out.jac, out.force, out.overflow


def _with_full_covariance(start: _Problem, y0, y, held: list[int], data: Dataset, result,
                          steps: int, solver, tol: Tolerances):
    """The core of the fit at `y` (the `held` leaves at their start values) with every
    other array as for `start`, the problem before any hold: the covariance then spans the
    held leaves too, so that the errors of the others include what the data leave free
    (a parameter that trades off with an undetermined one is not reported sharper than it
    is); the held leaves' own errors are reported as unknown (`FitResult.undetermined`)."""
    coord = np.isin(start.layout.coordinate_leaf(), held)
    y_full = jnp.asarray(np.where(coord, np.asarray(y0), np.asarray(y)))
    resid, jac, force, overflow = _evaluate_at(start, y_full, data, solver, tol)
    return _finish(start, y_full, data, resid, jac, force, overflow, result,
                   jnp.asarray(steps)), start


def _hold_accepted(free_fit, reason, kind, result, out, held, n_obs: int) -> bool:
    """Whether the fit with the undetermined leaves held at their start stands: it stopped
    by a rule that converges, and its sum of squares exceeds that of the fit before the
    hold (`free_fit`) by no more than chance allows, a likelihood-ratio test at 5 %
    (``chi-square`` with one degree of freedom per held leaf, in noise variances of the
    free fit). Otherwise the held leaves are no undetermined parameters, only ones whose
    error is large where the fit stood (a bent start the fit has left, a saturated
    transform), and holding them would pull the fit away from the data."""
    if reason is None or kind != "converged" or result != optx.RESULTS.successful:
        return False
    free_cost, free_held = free_fit[7], free_fit[6]
    k = len(held) - len(free_held)
    p = free_fit[5].layout.n_free()
    s2 = 2.0 * free_cost / max(n_obs - p, 1)
    cost = 0.5 * float(np.sum(np.asarray(out.resid) ** 2))
    return cost - free_cost <= s2 * float(gammaincinv(0.5 * k, 0.95))  # chi2.ppf / 2


def solve_chunked(problem: _Problem, y0, data: Dataset, solver, max_steps: int,
                  tol: Tolerances | None = None,
                  progress: Callable[[_Progress], None] | None = None) -> Solved:
    """Solve in chunks (module docstring): until a stopping rule fires, then, if the data
    leave some parameters undetermined (`undetermined_leaves`), hold them at their start
    and go on with the others from where the fit stood (within the same `max_steps`)."""
    tol = Tolerances() if tol is None else tol
    if max_steps <= 0:
        resid, jac, force, overflow = _evaluate_at(problem, y0, data, solver, tol)
        core = _finish(problem, y0, data, resid, jac, force, overflow,
                       optx.RESULTS.nonlinear_max_steps_reached, jnp.asarray(0))
        return Solved(core, "max_steps = 0: no step taken", problem, stop="max_steps")
    y, steps, start = y0, 0, problem
    n_obs = int(np.sum(np.asarray(data.weights) > 0))
    d = np.zeros(np.shape(y0))
    step_size = jnp.zeros(())
    history = [(0, np.inf, np.asarray(y0))]  # (steps, cost, y) after each call
    result, reason, kind, out = optx.RESULTS.successful, None, None, None
    held: list[int] = []
    unheld: list[int] = []
    free_fit = None  # the fit as it stood before its first hold
    t0 = time.perf_counter()
    while steps < max_steps:
        budget = _next_budget(steps, max_steps)
        out = _run(problem, y, d, data, solver, budget, step_size, tol)
        taken = int(out.num_steps)
        steps += taken
        result = out.result
        cost = 0.5 * float(np.sum(np.asarray(out.resid) ** 2))
        if result != optx.RESULTS.successful or not np.isfinite(cost):
            why = status_name(result) if np.isfinite(cost) else "non-finite cost"
            reason, kind, y = f"the solver stopped ({why})", "failed", out.y
            break
        # (The start's cost is not evaluated: inf, so the cost rules wait for a reference.)
        reason, kind = _stop_reason(out, budget, cost, _reference(history, steps), tol)
        y, step_size = out.y, out.step_size
        history.append((steps, cost, np.asarray(y)))
        d = np.maximum(d, _column_norms(out.jac))
        if progress is not None:
            progress(_Progress(steps, cost, time.perf_counter() - t0))
        if reason is not None or steps >= max_steps:
            # Judged only where the model explains the data (R2 >= MIN_R2; the residuals
            # are in units of the force's standard deviation): elsewhere ``s^2`` is no
            # estimate of the noise, and the result is not converged anyway.
            pinned = np.flatnonzero(np.asarray(_at_bound(problem.layout, out.y)))
            more = undetermined_leaves(out.jac, out.resid, problem.layout, n_obs,
                                       tol.undetermined, set(pinned.tolist())
                                       ) if 2 * cost / n_obs <= 1 - MIN_R2 else []
            if not more or steps >= max_steps:  # (no steps left to refit with them held)
                unheld = more
                break
            if free_fit is None:
                free_fit = (y, out, result, reason, kind, problem, list(held), cost)
            # Held at the start; the others go on from here (the cost rules start again)
            # with the trust region where it stood: it was learnt on the other
            # coordinates, which have not moved.
            held += more
            problem = _hold(problem, more)
            history = [(steps, np.inf, np.asarray(y))]
            reason, kind = None, None
    if free_fit is not None and not _hold_accepted(free_fit, reason, kind, result, out,
                                                   held, n_obs):
        unheld = held[len(free_fit[6]):]
        y, out, result, reason, kind, problem, held, _ = free_fit
    return _solved(start, problem, y0, y, data, out, result, reason, kind, steps,
                   max_steps, held, unheld, solver, tol)


def _solved(start, problem, y0, y, data, out, result, reason, kind, steps, max_steps,
            held, unheld, solver, tol: Tolerances) -> Solved:
    """The `Solved` of `solve_chunked` from its last chunk `out` at `y`."""
    if reason is None:
        result, reason, kind = (optx.RESULTS.nonlinear_max_steps_reached,
                                f"max_steps = {max_steps} reached", "max_steps")
    elif result == optx.RESULTS.successful and kind != "converged":
        result = optx.RESULTS.nonlinear_divergence
    if held:  # the core of the problem before the hold, whose program is compiled
        core, problem = _with_full_covariance(start, y0, y, held, data, result, steps,
                                              solver, tol)
    else:
        core = _finish(problem, y, data, out.resid, out.jac, out.force, out.overflow,
                       result, jnp.asarray(steps))
    names = [tuple(problem.layout.names[i] for i in k) for k in (held, unheld)]
    return Solved(core, reason + _held_words(*names), problem, names[0] + names[1], kind)


def solve_chunked_batch(problem: _Problem, y0, data: Dataset, solver, max_steps: int,
                        tol: Tolerances | None = None, vectorize: bool = False
                        ) -> tuple[_Core, list[str]]:
    """`solve_chunked` for B independent datasets (a leading axis on `data`), side by side:
    each round runs one chunk of every dataset not yet done in one compiled call
    (`_chunk_batch`; a dataset that is done gets a budget of 0), and each dataset follows
    the same scaling, chunk sizes and stopping rules as `solve_chunked` on its own, so it
    stops where `fit` would. Undetermined parameters are not held (the problem is shared).
    Returns the batched core, why each dataset stopped and its kind of stop (as
    `Solved.stop`)."""
    tol = Tolerances() if tol is None else tol
    count = jax.tree.leaves(data)[0].shape[0]
    y0 = np.asarray(y0)
    ys = np.tile(y0, (count, 1))
    steps = np.zeros(count, dtype=int)
    d = np.zeros(ys.shape)
    step_size = np.zeros(count)
    history = [[(0, np.inf, y0)] for _ in range(count)]
    done = np.zeros(count, dtype=bool) if max_steps > 0 else np.ones(count, dtype=bool)
    reasons: list[str | None] = [None] * count
    kinds: list[str | None] = [None] * count
    results = [optx.RESULTS.successful] * count
    last: list[_ChunkOut | None] = [None] * count
    rule = (jnp.asarray(tol.decrease, float), jnp.asarray(tol.undetermined, float))
    while not done.all():
        budget = np.array([0 if done[i] else _next_budget(steps[i], max_steps)
                           for i in range(count)])
        inv_d = np.stack([_inverse_scale(d[i]) for i in range(count)])
        outs = _chunk_batch(problem, jnp.asarray(ys), jnp.asarray(inv_d), data, solver,
                            jnp.asarray(budget, jnp.int32), jnp.asarray(step_size), *rule,
                            vectorize)
        outs = jax.tree.map(np.asarray, outs)
        for i in np.flatnonzero(~done):
            out = jax.tree.map(lambda a, i=i: a[i], outs)
            last[i] = out
            steps[i] += int(out.num_steps)
            results[i] = out.result
            cost = 0.5 * float(np.sum(out.resid**2))
            if out.result != optx.RESULTS.successful or not np.isfinite(cost):
                why = status_name(out.result) if np.isfinite(cost) else "non-finite cost"
                reasons[i], ys[i], done[i] = f"the solver stopped ({why})", out.y, True
                kinds[i] = "failed"
                continue
            reasons[i], kinds[i] = _stop_reason(
                out, int(budget[i]), cost, _reference(history[i], steps[i]), tol)
            ys[i], step_size[i] = out.y, out.step_size
            history[i].append((steps[i], cost, np.asarray(out.y)))
            d[i] = np.maximum(d[i], _column_norms(out.jac))
            done[i] = reasons[i] is not None or steps[i] >= max_steps
    return _finish_all(problem, y0, data, ys, steps, last, results, reasons, kinds,
                       max_steps)


def _finish_all(problem, y0, data, ys, steps, last, results, reasons, kinds,
                max_steps):
    """The batched core of `solve_chunked_batch` from each dataset's last chunk."""
    count = len(last)
    cores = []
    for i in range(count):
        if reasons[i] is None:
            results[i], kinds[i] = optx.RESULTS.nonlinear_max_steps_reached, "max_steps"
            reasons[i] = (f"max_steps = {max_steps} reached" if max_steps > 0 else
                          "max_steps = 0: no step taken")
        elif results[i] == optx.RESULTS.successful and kinds[i] != "converged":
            results[i] = optx.RESULTS.nonlinear_divergence
        if last[i] is None:  # no step taken: evaluated at the start
            data_i = jax.tree.map(lambda a, i=i: a[i], data)
            resid, jac, force, overflow = _evaluate(problem, jnp.asarray(y0), data_i)
            cores.append((y0, resid, jac, force, overflow))
        else:
            out = last[i]
            cores.append((ys[i], out.resid, out.jac, out.force, out.overflow))
    stacked = [jnp.asarray(np.stack([np.asarray(c[k]) for c in cores])) for k in range(5)]
    result = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(v) for v in a]), *results)
    y, resid, jac, force, overflow = stacked
    core = _finish_batch(problem, y, data, resid, jac, force, overflow, result,
                         jnp.asarray(steps))
    return core, [str(r) for r in reasons], [str(k) for k in kinds]
