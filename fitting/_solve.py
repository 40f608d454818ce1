"""The compiled solve: optimistix least squares on the residual of `_problem`, and in the
same compiled call everything the result needs (covariances by the delta method, the
condition number, metrics); batches of independent fits, on one device or spread over
several.
"""

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array

from jaxfric._compile import jit

from . import _params
from ._data import Dataset
from ._geodesic import GeodesicLevenbergMarquardt
from ._problem import _force_scale, _Problem, _residuals
from ._stopping import decrease_left, Stopping, Tolerances


# Eigenvalues of the equilibrated J^T J below this fraction of the largest are treated as
# this fraction: an undetermined direction then shows as an enormous (not NaN) stderr.
_EIG_FLOOR = 1e-15


def default_solver() -> GeodesicLevenbergMarquardt:
    """Levenberg-Marquardt with geodesic acceleration (`geodesic_solver`), ``rtol = atol =
    1e-6``, and MINPACK lmder's trust-region update: the region grows (x2) whenever a step
    achieves more than `GROW_RATIO` = 0.75 of the decrease the linear model predicts,
    instead of optimistix's default (x3.5 above 0.99 only). Near an optimum in a curved
    valley (LuGre's bristles, the Stribeck curve's Fc ~ Vs, the presliding shape) the steps
    achieve 0.95-0.99 of the prediction, so with optimistix's update the damping stays
    where it is and each step removes a fixed fraction of what is left. Growing by 3.5 at
    0.75 saves a few steps more but sent a fit with a cogging into a wrong period
    (tests/core/test_effects.py::test_joint_fit_recovers_hidden_effects), as did Nielsen's
    update. The acceleration keeps long steps on the floor of a curved valley, where
    the plain steps alternate between accepted and rejected (benchmarks/geodesic_steps.py
    compares them); its cost, one more simulation per step, is partly made up by the
    Jacobian, materialised once per accepted point (`fitting._geodesic`), where
    ``optx.LevenbergMarquardt`` runs the linearised simulation again for each damped solve
    and for the stopping rule: CPU per fit x1.17 against it where the steps do not drop,
    x0.8 where they do. ``optx.LevenbergMarquardt`` or any other
    optimistix least-squares solver can be passed as ``solver=``.

    The solver's own test stops when both the last step in ``y`` and the change of every
    residual are below ``atol + rtol*|value|``. ``y`` is of order one (scaled coordinates)
    and residuals are in units of the force's standard deviation, so 1e-6 means parameters
    settled to about 1e-6 relative, far below any standard error; the statistical rule of
    `fitting._stopping` usually stops the fit first.
    """
    return geodesic_solver()


def geodesic_solver(accelerate: bool = True) -> GeodesicLevenbergMarquardt:
    """Levenberg-Marquardt with geodesic acceleration (`fitting._geodesic`), the default;
    ``accelerate=False`` gives the same solver without it (the plain damped Gauss-Newton
    steps, the same trust region). Each accelerated step adds half the second-order
    correction of its path, from one more residual evaluation (one more simulation), so
    long steps stay on the floor of a curved valley."""
    return GeodesicLevenbergMarquardt(1e-6, 1e-6, optx.max_norm, _search(),
                                      accelerate=accelerate)


def _search() -> optx.ClassicalTrustRegion:
    """MINPACK lmder's trust-region update (`GROW_RATIO`, `GROW_FACTOR`)."""
    return optx.ClassicalTrustRegion(high_cutoff=GROW_RATIO, high_constant=GROW_FACTOR)


#: The trust region of `default_solver` grows by `GROW_FACTOR` after a step that achieves
#: more than `GROW_RATIO` of the predicted decrease (MINPACK lmder's 0.75 and 2).
GROW_RATIO = 0.75
GROW_FACTOR = 2.0


class _Core(eqx.Module):
    """Every array that comes out of one solve (vmapped for batches)."""

    y: Array
    result: optx.RESULTS
    num_steps: Array
    prediction: Array
    overflow: Array
    natural: Array
    cov_natural: Array
    cov_fit: Array
    rmse: Array
    nrmse: Array
    r2: Array
    condition_number: Array
    # For the `FitResult`, computed in the same compiled call (run op by op, they cost
    # the first fit of a session a few dozen small compilations):
    model: Any  # the fitted model as the user gave it (`PaperShape` if it had one)
    fit_model: Any  # the fitted model in the fit representation
    params: tuple[Array, ...]  # `natural` split into its entries
    stderr: tuple[Array, ...]
    corr: Array
    corr_fit: Array
    at_bound: Array  # one flag per leaf: free and pinned at a bound of its transform


def _r_factor(jac, resid, mask):
    """The ``(p + 1) x (p + 1)`` triangular factor R of the QR decomposition of
    ``[J * mask, resid]``: its first p columns are R of the free Jacobian, the top of its
    last column is ``Q^T resid``. One pass over the n x (p + 1) matrix gives what the
    covariance's condition number and `_remaining_step` need; an SVD of the n x p Jacobian
    with its left singular vectors takes several times longer at n = 1e5
    (benchmarks/profiling/profile_fit_fixed.py)."""
    jf = jnp.where(jnp.asarray(mask).astype(bool)[None, :], jac, 0.0)
    return jnp.linalg.qr(jnp.concatenate([jf, resid[:, None]], axis=1), mode="r")


def _covariance(jac, resid, mask, n_obs, r=None):
    """``s^2 (J^T J)^-1`` restricted to the free coordinates (zero rows/cols elsewhere).

    Columns are equilibrated first (unit norm) so that the eigen-decomposition sees the
    correlation structure, not the units; the condition number returned is that of the
    equilibrated free Jacobian (1 = orthogonal parameters; 1e8 = nearly collinear).
    `r`: `_r_factor` of the same arguments, if already computed.
    """
    r = _r_factor(jac, resid, mask) if r is None else r
    jac = jac * mask
    norms = jnp.linalg.norm(jac, axis=0)
    norms = jnp.where(norms > 0, norms, 1.0)
    jn = jac / norms
    a = jn.T @ jn + jnp.diag(1.0 - mask)
    eig, vec = jnp.linalg.eigh(a)
    eig = jnp.maximum(eig, _EIG_FLOOR * jnp.max(eig))
    inv = (vec / eig) @ vec.T
    n_free = jnp.sum(mask)
    dof = jnp.maximum(n_obs - n_free, 1.0)
    s2 = jnp.sum(resid**2) / dof
    cov = s2 * inv / jnp.outer(norms, norms) * jnp.outer(mask, mask)
    # Singular values (descending; the fixed columns give zeros) of the p x p factor R of
    # jn = QR, which are those of jn: on the CPU, `svd(jn, compute_uv=False)` allocates an
    # n x n buffer (80 GB at n = 1e5). jn's columns are J's scaled: its R is J's, scaled.
    p = jac.shape[1]
    sv = jnp.linalg.svd(r[:p, :p] / norms[None, :], compute_uv=False)
    k = jnp.maximum(n_free.astype(jnp.int32) - 1, 0)
    cond = jnp.where(n_free > 0, sv[0] / sv[k], 1.0)
    return cov, cond


def _remaining_step(jac, resid, mask, n_obs, r=None):
    """Length, in standard errors, of the Gauss-Newton step left at the solver's last
    point: ``sqrt(z2)`` with ``z2 = dy^T (J^T J / s^2) dy = |J dy|^2 / s^2`` for the step
    ``dy`` over the free coordinates and ``s^2 = RSS/n_obs``. `r`: `_r_factor` of the same
    arguments, if already computed."""
    r = _r_factor(jac, resid, mask) if r is None else r
    p = jac.shape[1]
    # |J dy|^2 is the squared projection of the residual onto the column space of J, over
    # the singular values that are not zero: with J = Q R and R = U S V^T, J's left singular
    # vectors are Q U, so their products with the residual are U^T (Q^T resid), from R alone
    # (never an n x n or n x p factor).
    u, sv, _ = jnp.linalg.svd(r[:p, :p])
    keep = sv > 1e-10 * jnp.max(sv)
    projected = jnp.sum(jnp.where(keep, u.T @ r[:p, p], 0.0) ** 2)
    z2 = projected / jnp.maximum(jnp.sum(resid**2) / n_obs, 1e-300)
    return jnp.sqrt(z2)


def _solve_impl(problem: _Problem, y0, data: Dataset, solver, max_steps: int,
                decrease=Tolerances.decrease, undetermined=Tolerances.undetermined) -> _Core:
    """The whole solve in one compiled loop of at most `max_steps` (static) steps: the
    path of minimisers in `fit` and `fit_batch` (least-squares solvers run in chunks,
    `fitting._chunked`). A least-squares
    solver stops on the same statistical rule as `fit` (`fitting._stopping.Stopping`,
    tested after every step) or on its own test."""
    scale = _force_scale(data)
    args = (problem, data, scale)
    if isinstance(solver, optx.AbstractLeastSquaresSolver):
        dtype = y0.dtype
        # (Its budget is past `max_steps`: optimistix's own limit then reports reaching it.)
        solver = Stopping(solver, jnp.asarray(max_steps + 1, jnp.int32), jnp.zeros((), dtype),
                          jnp.asarray(decrease, dtype), jnp.asarray(undetermined, dtype),
                          jnp.ones_like(y0), problem.layout.coordinate_mask(),
                          jnp.sum(data.weights > 0).astype(dtype))
    sol = optx.least_squares(
        _residuals, solver, y0, args, has_aux=True, max_steps=max_steps, throw=False
    )
    state = sol.state[0] if isinstance(solver, Stopping) else sol.state
    y = sol.value
    # The solver's last accepted point is `y`: its residuals, Jacobian and aux (the force)
    # are reused rather than recomputed, which would trace and compile the JVP of the
    # simulation a second time (the dominant cost of a fit). They are taken from the
    # solver's state, which holds them for `y`: `sol.aux` of the Gauss-Newton family is
    # the aux of the point accepted *before* `y` (optimistix returns `prev_aux` from each
    # step), so the prediction and RMSE would belong to another model than the one
    # returned (visibly so for a fit stopped at its step limit).
    f_info = getattr(state, "f_info", None)
    if isinstance(f_info, optx.FunctionInfo.ResidualJac):
        force, overflow = state.aux
        resid = f_info.residual.ravel()
        jac = f_info.jac.as_matrix()
    else:  # a minimiser: no Jacobian in its state; evaluate everything at `y`
        resid, jac, force, overflow = _evaluate_impl(problem, y, data)
    result = optx.RESULTS.where(sol.stats["num_steps"] == 0,
                                optx.RESULTS.nonlinear_max_steps_reached, sol.result)
    # A solve that never left its start is converged only if the start is an optimum (the
    # gradient test of `STUCK_COSINE`, as in `fitting._chunked`); otherwise it is stuck.
    # A residual at round-off (an exact fit) is an optimum whatever its direction.
    # A start that satisfies the statistical rule is an optimum too (a refit of a fit).
    mask = problem.layout.coordinate_mask()
    exact = jnp.sqrt(jnp.mean(resid**2)) <= EXACT_RESIDUAL
    left, _ = decrease_left(jac, resid, mask, jnp.sum(data.weights > 0).astype(y.dtype),
                            undetermined)
    stuck = jnp.all(y == y0) & ~exact & ~(left <= decrease) & (
        _max_cosine(jac, resid, mask) > STUCK_COSINE)
    result = optx.RESULTS.where(stuck & (result == optx.RESULTS.successful),
                                optx.RESULTS.nonlinear_divergence, result)
    return _finish_impl(problem, y, data, resid, jac, force, overflow, result,
                        sol.stats["num_steps"])


#: A fit none of whose steps moves it (or lowers the cost) is at its optimum if the largest
#: cosine between a free Jacobian column and the residual is at most this; otherwise stuck.
STUCK_COSINE = 1e-4
#: RMS of the scaled residuals (in units of the force's scale) below which a fit is exact.
EXACT_RESIDUAL = 1e-10
#: A fit is converged only if its R2 is at least this: the model explains at least a tenth
#: of the measured force's variance. A friction model that explains less has not fitted
#: the friction (a collapse to zero force, a velocity of the wrong sign); fits of friction
#: data explain far more (0.9 and above), so the threshold only catches failures.
MIN_R2 = 0.1


def _max_cosine(jac, resid, mask):
    """MINPACK's gradient test over the free columns: the largest ``|J_i . r| / (|J_i| |r|)``
    (0 for a zero residual or no free column)."""
    norms = jnp.linalg.norm(jac, axis=0) * jnp.linalg.norm(resid)
    cos = jnp.abs(jac.T @ resid) / jnp.where(norms > 0, norms, 1.0)
    return jnp.max(jnp.where((norms > 0) & (mask > 0), cos, 0.0))


def _evaluate_impl(problem: _Problem, y, data: Dataset):
    """Residuals, Jacobian, force and overflow count at `y` (a separate evaluation)."""
    args = (problem, data, _force_scale(data))

    def resid_fn(yy):
        return _residuals(yy, args)[0].ravel()

    force, overflow = _residuals(y, args)[1]
    return resid_fn(y), jax.jacfwd(resid_fn)(y), force, overflow


def _finish_impl(problem: _Problem, y, data: Dataset, resid, jac, force, overflow, result,
                 num_steps) -> _Core:
    """Everything a `FitResult` needs at the solution `y`, from its residuals and Jacobian
    (no further simulation)."""
    overflow = overflow.astype(jnp.int32)
    observed = data.weights > 0
    n_obs = jnp.sum(observed).astype(y.dtype)
    mask = problem.layout.coordinate_mask()
    r = _r_factor(jac, resid, mask)
    cov_y, cond = _covariance(jac, resid, mask, n_obs, r)
    result = optx.RESULTS.where(  # see `FitResult`: dithering at the optimum is converged
        (result == optx.RESULTS.nonlinear_max_steps_reached) & (num_steps > 0)
        & (_remaining_step(jac, resid, mask, n_obs, r) < 0.03),
        optx.RESULTS.successful, result)

    # Delta method: covariances of the reported (paper) parameters and of the fit
    # representation's own parameters, from cov(y).
    def natural_fn(yy):
        return _params.natural_vector(problem.user_model(yy))

    def fit_fn(yy):
        return _params.natural_vector(problem.model(yy))

    g = jax.jacfwd(natural_fn)(y)
    g_fit = jax.jacfwd(fit_fn)(y)

    err = jnp.where(observed, force - data.F, 0.0)
    rmse = jnp.sqrt(jnp.sum(err**2) / n_obs)
    # A fit whose error is not finite (an overflowing sample, a diverged model) has not
    # converged, whatever the solver's own test said.
    result = optx.RESULTS.where(jnp.isfinite(rmse), result, optx.RESULTS.nonfinite)
    f_obs_mean = jnp.sum(jnp.where(observed, data.F, 0.0)) / n_obs
    ss_tot = jnp.sum(jnp.where(observed, (data.F - f_obs_mean) ** 2, 0.0))
    r2 = 1.0 - jnp.sum(err**2) / ss_tot
    # Honest status: a stopping rule that fired is not enough; the data must be explained
    # (`MIN_R2`) and no parameter may sit pinned at a bound of its transform.
    at_bound = problem.layout.at_bound(y)
    result = optx.RESULTS.where(
        (result == optx.RESULTS.successful) & ((r2 < MIN_R2) | jnp.any(at_bound)),
        optx.RESULTS.nonlinear_divergence, result)
    f_range = jnp.max(jnp.where(observed, data.F, -jnp.inf)) - jnp.min(
        jnp.where(observed, data.F, jnp.inf)
    )
    natural = natural_fn(y)
    cov_natural = g @ cov_y @ g.T
    cov_fit = g_fit @ cov_y @ g_fit.T
    sd = jnp.sqrt(jnp.diagonal(cov_natural))
    return _Core(
        y=y,
        result=result,
        num_steps=jnp.asarray(num_steps),
        prediction=force,
        overflow=overflow,
        natural=natural,
        cov_natural=cov_natural,
        cov_fit=cov_fit,
        rmse=rmse,
        nrmse=rmse / f_range,
        r2=r2,
        condition_number=cond,
        model=problem.user_model(y),
        fit_model=problem.model(y),
        params=tuple(natural[i] for i in range(natural.shape[0])),
        stderr=tuple(sd[i] for i in range(sd.shape[0])),
        corr=_correlation(cov_natural),
        corr_fit=_correlation(cov_fit),
        at_bound=at_bound,
    )


_solve = jit(_solve_impl)


@jit
def _solve_batch(problem, y0, data, solver, max_steps, vectorize=False,
                 decrease=Tolerances.decrease, undetermined=Tolerances.undetermined):
    # Over datasets only; returning arrays and the result code (never the whole optimistix
    # Solution, whose state holds jaxprs that cannot be batched: optimistix issues #38 and
    # #63). A failure in one dataset only shows in its own `result`.
    # `lax.map` (default): one dataset after the other through the unbatched solve, which
    # on a CPU compiles and runs faster than the vmapped loop, and each dataset stops at
    # its own termination (under `vmap` the loop runs until the slowest dataset stops;
    # benchmarks/throughput.py compares both). `vmap` (`vectorize=True`): one loop for
    # all, for accelerators.
    def one(d):
        return _solve_impl(problem, y0, d, solver, max_steps, decrease, undetermined)

    return jax.vmap(one)(data) if vectorize else jax.lax.map(one, data)


def _correlation(cov):
    sd = jnp.sqrt(jnp.diagonal(cov, axis1=-2, axis2=-1))
    denom = sd[..., :, None] * sd[..., None, :]
    return jnp.where(denom > 0, cov / jnp.where(denom > 0, denom, 1.0), jnp.nan)


def device_shares(data, devices) -> list[tuple[int, object, object]]:
    """``[(size, share, device)]``: the B datasets of `data` (a leading axis on every
    leaf) split into contiguous shares, one per device; the last share is padded with
    copies of its last dataset, so that all shares have one shape (one compilation).
    `join_shares` drops the copies."""
    count = jax.tree.leaves(data)[0].shape[0]
    share = -(-count // len(devices))
    out = []
    for k, device in enumerate(devices):
        lo, hi = k * share, (k + 1) * share
        part = jax.tree.map(lambda a, lo=lo, hi=hi: np.asarray(a[lo:hi]), data)
        size = jax.tree.leaves(part)[0].shape[0]
        if size == 0:
            break
        if size < share:
            part = jax.tree.map(
                lambda a, pad=share - size: np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]),
                part)
        out.append((size, part, device))
    return out


def join_shares(results) -> object:
    """The results ``[(size, batched result)]`` of `device_shares`, padding dropped,
    concatenated along the batch axis."""
    shares = [jax.tree.map(lambda a, n=size: np.asarray(a)[:n], out) for size, out in results]
    return jax.tree.map(lambda *parts: np.concatenate(parts), *shares)


def _solve_batch_on_devices(problem, y0, data, solver, max_steps, devices, vectorize,
                            decrease=Tolerances.decrease,
                            undetermined=Tolerances.undetermined):
    """`_solve_batch` with the B datasets split into contiguous shares, one per device
    (`device_shares`).

    Each share is placed on its device and solved there by the same compiled function;
    JAX dispatches asynchronously, so the devices work at the same time, and the solver
    loops never wait for one another (a GSPMD-partitioned `vmap` would synchronise every
    iteration of every loop across devices)."""
    pending = []
    for size, part, device in device_shares(data, devices):
        problem_k, y0_k, part = jax.device_put((problem, y0, part), device)
        pending.append((size, _solve_batch(problem_k, y0_k, part, solver, max_steps,
                                           vectorize, decrease, undetermined)))
    return join_shares(pending)
