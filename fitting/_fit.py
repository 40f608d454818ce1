"""Least-squares fits of any jaxfric model to measured ``(t, x, F)``.

**Solver.** `optimistix.LevenbergMarquardt` by default, because:

- the problem is a nonlinear least-squares problem with many more samples than parameters
  (thousands against 5-25), so a Gauss-Newton method that uses ``J^T J`` as its curvature
  model converges in tens of steps where a quasi-Newton minimiser (BFGS) needs hundreds, and
  ``J`` costs only p forward-mode JVPs through the simulation;
- the presliding parameters are strongly correlated and some are weakly determined by a
  given experiment (C by presliding data, say), so ``J^T J`` is nearly singular: pure
  Gauss-Newton would take huge steps along those directions, while the Levenberg-Marquardt
  damping ``lambda*I`` (a trust region) keeps the steps bounded and still reduces to
  Gauss-Newton near the optimum;
- the damped step is solved by QR of ``[J; sqrt(lambda) I]`` (optimistix's default), which
  does not square the condition number the way the normal equations would.

`optimistix.Dogleg` or `optimistix.IndirectLevenbergMarquardt` can be passed as ``solver``
instead; any optimistix minimiser also works (it minimises the sum of squares).

**Residual.** ``r = sqrt(w) * (simulate(model) - F) / scale`` with ``scale`` the standard
deviation of the measured force: dimensionless residuals of order one, so the solver's
tolerances mean the same thing for a 2 N tribometer and a 30 N linear guide.

**Unknowns.** The solver sees the unconstrained, scaled vector ``y`` of *all* parameter leaves
(see `_transforms`); a held leaf keeps its value and so has a zero Jacobian column, which
the damped QR step leaves at zero. The free set is therefore data, not structure: stages of
a staged fit with different free parameters share one compilation.

**Compilation.** The free set is a traced mask (above), `lax.map` loops over the
experiments of one fit, and a custom JVP materialises the Jacobian once per evaluation
(`_dense_forces_jvp`): compile time, not run time, dominates a fit of the two-state model.

**Uncertainties.** At the optimum, ``cov(y) = s^2 (J^T J)^-1`` over the free coordinates with
``s^2 = RSS/(N - p)`` (N samples with weight > 0, p free coordinates), then
``cov(theta) = G cov(y) G^T`` with ``G = d theta/d y`` (delta method) for the paper's natural SI
parameters ``theta``, including those derived through a reparameterisation (``a..beta``).
"""

import dataclasses
import warnings
from collections.abc import Iterable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array

import jaxfric

from . import _params
from ._data import check_dataset, Dataset, stack
from ._shape import NormalizedPaperShape


#: Result codes by name (`optimistix.RESULTS` includes lineax's).
_RESULT_NAMES = ("successful", "nonlinear_max_steps_reached", "nonlinear_divergence",
                 "nonfinite", "max_steps_reached", "singular", "breakdown", "stagnation",
                 "conlim", "nonfinite_input")

# Eigenvalues of the equilibrated J^T J below this fraction of the largest are treated as
# this fraction: an undetermined direction then shows as an enormous (not NaN) stderr.
_EIG_FLOOR = 1e-15


def default_solver() -> optx.LevenbergMarquardt:
    """``optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6)`` (see the module docstring).

    optimistix stops when both the last step in ``y`` and the change of every residual are
    below ``atol + rtol*|value|``. ``y`` is of order one (scaled coordinates) and residuals
    are in units of the force's standard deviation, so 1e-6 means parameters settled to
    about 1e-6 relative, far below any standard error, while tighter tolerances only make
    the last iterations dither.
    """
    return optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6)


class _Problem(eqx.Module):
    """What the jitted solve needs besides the data: the starting model in the fit
    representation, how its leaves map to ``y``, and whether to report a `PaperShape`."""

    template: Any
    layout: _params.Layout
    paper_shape: bool = eqx.field(static=True)
    max_reversals: int | None = eqx.field(static=True, default=None)

    def bounded(self, data: Dataset) -> "_Problem":
        """This problem with a static bound on the reversals of `data` (stacked, concrete
        arrays ``(..., n)``), which the two-state simulation uses to evaluate its reversal
        terms on a short list (`jaxfric.simulate`, ``max_reversals``)."""
        t, x = np.asarray(data.t), np.asarray(data.x)
        v = None if data.v is None else np.asarray(data.v)
        t2, x2 = t.reshape(-1, t.shape[-1]), x.reshape(-1, x.shape[-1])
        v2 = None if v is None else v.reshape(-1, v.shape[-1])
        bound = max(jaxfric.reversal_bound(t2[i], x2[i], None if v2 is None else v2[i])
                    for i in range(t2.shape[0]))
        return dataclasses.replace(self, max_reversals=bound)

    def model(self, y):
        return _params.from_vector(y, self.template, self.layout)

    def user_model(self, y):
        model = self.model(y)
        if self.paper_shape:
            get = _params.two_state_part(model)
            two = get(model)
            model = eqx.tree_at(lambda m: get(m).shape, model,
                                two.shape.to_paper(two.stribeck.Fs))
        return model


def _simulate_stack(model, data: Dataset, max_reversals: int | None = None):
    """Force (N) and stack-overflow count for stacked datasets, arrays ``(D, n)``.

    `lax.map` (a loop), not `vmap`, over the D experiments of one fit: the simulation and
    its Jacobian are then compiled once, unbatched, which compiles several times faster
    than their batched version and runs as fast on CPU.
    """
    model_ = model

    def one(d):
        t, x, v = d
        out = jaxfric.simulate(model_, t, x, v, full_output=True,
                               max_reversals=max_reversals)
        return out.force, out.overflow

    force, overflow = jax.lax.map(one, (data.t, data.x, data.v))
    return force, jnp.sum(overflow)


def _force_scale(data: Dataset) -> Array:
    """Weighted standard deviation of the measured force (N); 1 if it is 0."""
    w = data.weights
    mean = jnp.sum(w * data.F) / jnp.sum(w)
    std = jnp.sqrt(jnp.sum(w * (data.F - mean) ** 2) / jnp.sum(w))
    return jnp.where(std > 0, std, 1.0)


def _forces(y, problem: _Problem, data: Dataset):
    """Model force ``(D, n)`` for the vector `y`, and the stack-overflow count (as a float,
    so that it can ride along through the custom JVP below)."""
    force, overflow = _simulate_stack(problem.model(y), data, problem.max_reversals)
    return force, overflow.astype(force.dtype)


@eqx.filter_custom_jvp
def _dense_forces(y, problem, data):
    return _forces(y, problem, data)


@_dense_forces.def_jvp
def _dense_forces_jvp(primals, tangents):
    # Why a custom JVP: compiling the simulation's JVP is by far the dominant cost of a
    # fit, and Levenberg-Marquardt uses the linearised residual several times per step
    # (materialising J for the QR solve, the trust region's predicted reduction, ...), each
    # use a fresh copy of the linearised simulation in the compiled loop. Computing J once
    # per evaluation with `jacfwd` here turns every later use into a matrix product. On a
    # 1200-sample two-state fit: compile 28 s -> 18 s, run 1.7 s -> 0.3 s; for a vmapped
    # batch of 32: compile 83 s -> 35 s. (Only `y` is differentiated; data and problem
    # are constants of the fit.)
    y, problem, data = primals
    t_y = tangents[0]

    def both(yy):
        out = _forces(yy, problem, data)
        return out[0], out

    jac, out = jax.jacfwd(both, has_aux=True)(y)
    if t_y is None:
        t_y = jnp.zeros_like(y)
    return out, (jac @ t_y, jnp.zeros_like(out[1]))


def _residuals(y, args):
    """Dimensionless residuals, with the simulated force and overflow count as aux."""
    problem, data, scale = args
    force, overflow = _dense_forces(y, problem, data)
    return jnp.sqrt(data.weights) * (force - data.F) / scale, (force, overflow)


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


def _covariance(jac, resid, mask, n_obs):
    """``s^2 (J^T J)^-1`` restricted to the free coordinates (zero rows/cols elsewhere).

    Columns are equilibrated first (unit norm) so that the eigen-decomposition sees the
    correlation structure, not the units; the condition number returned is that of the
    equilibrated free Jacobian (1 = orthogonal parameters; 1e8 = nearly collinear).
    """
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
    # n x n buffer (80 GB at n = 1e5).
    sv = jnp.linalg.svd(jnp.linalg.qr(jn, mode="r"), compute_uv=False)
    k = jnp.maximum(n_free.astype(jnp.int32) - 1, 0)
    cond = jnp.where(n_free > 0, sv[0] / sv[k], 1.0)
    return cov, cond


def _remaining_step(jac, resid, mask, n_obs):
    """Length, in standard errors, of the Gauss-Newton step left at the solver's last
    point: ``sqrt(z2)`` with ``z2 = dy^T (J^T J / s^2) dy = |J dy|^2 / s^2`` for the step
    ``dy`` over the free coordinates and ``s^2 = RSS/n_obs``."""
    jf = jnp.where(mask[None, :], jac, 0.0)
    # |J dy|^2 is the squared projection of the residual onto the column space of J: from
    # the thin SVD (n x p, never n x n), over the singular values that are not zero.
    u, sv, _ = jnp.linalg.svd(jf, full_matrices=False)
    keep = sv > 1e-10 * jnp.max(sv)
    projected = jnp.sum(jnp.where(keep, u.T @ resid, 0.0) ** 2)
    z2 = projected / jnp.maximum(jnp.sum(resid**2) / n_obs, 1e-300)
    return jnp.sqrt(z2)


def _solve_impl(problem: _Problem, y0, data: Dataset, solver, max_steps: int) -> _Core:
    scale = _force_scale(data)
    args = (problem, data, scale)
    sol = optx.least_squares(
        _residuals, solver, y0, args, has_aux=True, max_steps=max_steps, throw=False
    )
    y = sol.value
    # The solver's last accepted point is `y`: its residuals, Jacobian and aux (the force)
    # are reused rather than recomputed, which would trace and compile the JVP of the
    # simulation a second time (the dominant cost of a fit).
    force, overflow = sol.aux
    overflow = overflow.astype(jnp.int32)
    f_info = getattr(sol.state, "f_info", None)
    if isinstance(f_info, optx.FunctionInfo.ResidualJac):
        resid = f_info.residual.ravel()
        jac = f_info.jac.as_matrix()
    else:  # a minimiser: no Jacobian in its state
        def resid_fn(yy):
            return _residuals(yy, args)[0].ravel()

        resid = resid_fn(y)
        jac = jax.jacfwd(resid_fn)(y)
    observed = data.weights > 0
    n_obs = jnp.sum(observed).astype(y.dtype)
    cov_y, cond = _covariance(jac, resid, problem.layout.coordinate_mask(), n_obs)
    result = optx.RESULTS.where(  # see `FitResult`: dithering at the optimum is converged
        (sol.result == optx.RESULTS.nonlinear_max_steps_reached)
        & (_remaining_step(jac, resid, problem.layout.coordinate_mask(), n_obs) < 0.03),
        optx.RESULTS.successful, sol.result)

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
    f_obs_mean = jnp.sum(jnp.where(observed, data.F, 0.0)) / n_obs
    ss_tot = jnp.sum(jnp.where(observed, (data.F - f_obs_mean) ** 2, 0.0))
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
        num_steps=sol.stats["num_steps"],
        prediction=force,
        overflow=overflow,
        natural=natural,
        cov_natural=cov_natural,
        cov_fit=cov_fit,
        rmse=rmse,
        nrmse=rmse / f_range,
        r2=1.0 - jnp.sum(err**2) / ss_tot,
        condition_number=cond,
        model=problem.user_model(y),
        fit_model=problem.model(y),
        params=tuple(natural[i] for i in range(natural.shape[0])),
        stderr=tuple(sd[i] for i in range(sd.shape[0])),
        corr=_correlation(cov_natural),
        corr_fit=_correlation(cov_fit),
    )


_solve = eqx.filter_jit(_solve_impl)


@eqx.filter_jit
def _solve_batch(problem, y0, data, solver, max_steps, vectorize=False):
    # Over datasets only; returning arrays and the result code (never the whole optimistix
    # Solution, whose state holds jaxprs that cannot be batched: optimistix issues #38 and
    # #63). A failure in one dataset only shows in its own `result`.
    # `lax.map` (default): one dataset after the other through the unbatched solve, which
    # on a CPU compiles and runs faster than the vmapped loop, and each dataset stops at
    # its own termination (under `vmap` the loop runs until the slowest dataset stops;
    # benchmarks/throughput.py compares both). `vmap` (`vectorize=True`): one loop for
    # all, for accelerators.
    def one(d):
        return _solve_impl(problem, y0, d, solver, max_steps)

    return jax.vmap(one)(data) if vectorize else jax.lax.map(one, data)


def _correlation(cov):
    sd = jnp.sqrt(jnp.diagonal(cov, axis1=-2, axis2=-1))
    denom = sd[..., :, None] * sd[..., None, :]
    return jnp.where(denom > 0, cov / jnp.where(denom > 0, denom, 1.0), jnp.nan)


def status_name(result: optx.RESULTS) -> str | list[str]:
    """The name of an optimistix result code (e.g. ``"successful"``,
    ``"nonlinear_max_steps_reached"``); a list for a batch of codes."""
    codes = [(n, getattr(optx.RESULTS, n)) for n in _RESULT_NAMES if hasattr(optx.RESULTS, n)]
    # `==` on an enumeration item gives a (possibly batched) boolean array.
    hits = [(n, np.asarray(result == item)) for n, item in codes]
    shape = hits[0][1].shape
    out = np.full(shape, "unknown", dtype=object)
    for n, hit in reversed(hits):
        out = np.where(hit, n, out)
    return str(out) if out.ndim == 0 else [str(s) for s in out.ravel()]


class FitResult(eqx.Module):
    """The outcome of `fit` (or, with a leading batch axis on every array, of `fit_batch`).

    **Attributes:**

    - `model`: the fitted model, in the representation it was given in (a `PaperShape`
      stays a `PaperShape`).
    - `params`: ``{name: value}`` in SI units with the paper's names (two-state:
      Fs, Fc, Vs, delta, sigma2, a, b, c, alpha, beta, l1, C; GMS: ..., nu_i, k_i).
    - `stderr`: ``{name: standard error}`` (delta method from the Jacobian at the optimum);
      0 for held parameters.
    - `cov`, `corr`: covariance and correlation of `params` in `names` order (NaN rows for
      held parameters). With a reparameterised `PaperShape`, a/b/c show the near +-1
      correlations that the reparameterisation removed from the fit itself.
    - `fit_names`, `cov_fit`, `corr_fit`: the parameters of the representation the solver
      worked in (for a `PaperShape`: ``l1, alpha, beta_rel, curvature, quartic`` of
      `NormalizedPaperShape`), their covariance (SI) and correlation: how well conditioned
      the fit itself was. (The transforms are elementwise, so these correlations are also
      those of the solver's unconstrained coordinates.)
    - `prediction`, `residuals`: model force and ``prediction - F`` (N) per sample.
    - `rmse` (N) over samples of weight > 0; `nrmse` = rmse / (max F - min F), the *range*
      of the measured force; `r2` = 1 - SS_res / SS_tot.
    - `condition_number`: of the column-equilibrated Jacobian of the free coordinates.
    - `result`: the `optimistix.RESULTS` code; `num_steps`: solver iterations. A solve that
      reaches `max_steps` while the Gauss-Newton step left at its last point is shorter than
      0.03 standard errors is reported as successful: it is at the optimum, and only the
      Levenberg-Marquardt stopping rule (every residual's change below tolerance on an
      accepted step) failed to fire because round-off made it reject its steps.
    - `free`: names of the fitted leaves; `overflow`: memory-stack overflows in the final
      simulation (0 unless the model's ``stack_size`` is too small).

    Properties: `converged` (result is successful), `status` (the code's name).
    """

    model: Any
    params: dict[str, Array]
    stderr: dict[str, Array]
    cov: Array
    corr: Array
    cov_fit: Array
    corr_fit: Array
    prediction: Any
    residuals: Any
    rmse: Array
    nrmse: Array
    r2: Array
    condition_number: Array
    result: optx.RESULTS
    num_steps: Array
    overflow: Array
    names: tuple[str, ...] = eqx.field(static=True)
    fit_names: tuple[str, ...] = eqx.field(static=True)
    free: tuple[str, ...] = eqx.field(static=True)

    @property
    def converged(self) -> Array:
        return self.result == optx.RESULTS.successful

    @property
    def status(self) -> str | list[str]:
        return status_name(self.result)

    def __getitem__(self, i) -> "FitResult":
        """Dataset `i` of a batched result (from `fit_batch`)."""
        return jax.tree.map(lambda a: a[i], self)

    def summary(self) -> str:
        """A plain-text table: name, value, standard error, relative error (one fit; for
        a batch use ``result[i].summary()``)."""
        head = (f"status: {self.status}   steps: {int(self.num_steps)}   "
                f"RMSE: {float(self.rmse):.4g} N   NRMSE: {float(self.nrmse):.4g}   "
                f"R2: {float(self.r2):.6f}")
        lines = [head]
        for name in self.names:
            v, s = float(self.params[name]), float(self.stderr[name])
            rel = f"{100 * s / abs(v):9.3g} %" if v != 0 else ""
            lines.append(f"  {name:>10s} = {v: .6e}  +- {s:.2e} {rel}")
        return "\n".join(lines)


def _problem(model, props, free, reparameterize):
    """The solver's view of `model` (given in the user's representation) and ``y0``."""
    fit_model = _params.to_fit_representation(model, reparameterize)
    get = _params.two_state_part(model)
    paper_shape = get is not None and isinstance(get(model).shape, jaxfric.PaperShape) and (
        isinstance(get(fit_model).shape, NormalizedPaperShape))
    return _problem_from_fit(fit_model, props, free, paper_shape)


def _problem_from_fit(fit_model, props, free, paper_shape: bool):
    """As `_problem` for a model already in the fit representation; `paper_shape` says
    whether results are reported with a `PaperShape`."""
    fit_model = _params.as_float_arrays(fit_model)
    if props is None:
        props = _params.default_props(fit_model)
    if free is not None:
        props = _params.set_free(fit_model, props, free)
    layout = _params.make_layout(fit_model, props)
    problem = _Problem(template=fit_model, layout=layout, paper_shape=paper_shape)
    return problem, _params.to_vector(fit_model, layout)


def _assemble(problem: _Problem, core: _Core, prediction, residuals) -> FitResult:
    """Turn solver arrays into a `FitResult` (works on batched cores too)."""
    layout = problem.layout
    batched = core.y.ndim == 2

    def first(model):  # names and structure do not depend on the values
        return jax.tree.map(lambda a: np.asarray(a)[0], model) if batched else model

    names = _params.natural_names(first(core.model))
    leaf_free = np.asarray(layout.leaf_free)
    return FitResult(
        model=core.model,
        params=dict(zip(names, core.params)),
        stderr=dict(zip(names, core.stderr)),
        cov=core.cov_natural,
        corr=core.corr,
        cov_fit=core.cov_fit,
        corr_fit=core.corr_fit,
        prediction=prediction,
        residuals=residuals,
        rmse=core.rmse,
        nrmse=core.nrmse,
        r2=core.r2,
        condition_number=core.condition_number,
        result=core.result,
        num_steps=core.num_steps,
        overflow=core.overflow,
        names=names,
        fit_names=_params.natural_names(first(core.fit_model)),
        free=tuple(n for n, f in zip(layout.names, leaf_free) if f),
    )


def _warn_overflow(core: _Core) -> None:
    total = int(np.sum(np.asarray(core.overflow)))
    if total > 0:
        warnings.warn(
            f"the fitted model's memory stack overflowed {total} time(s) on the data; "
            "increase the model's stack_size",
            jaxfric.StackOverflowWarning,
            stacklevel=3,
        )


def _fit_stacked(problem: _Problem, y0, checked: Sequence[Dataset], data: Dataset, solver,
                 max_steps: int):
    """Solve for checked datasets stacked (and possibly re-weighted) into `data`.

    Returns the `FitResult` (per-dataset `prediction`/`residuals` tuples, padding removed)
    and the fitted model in the fit representation (to chain stages without a round trip
    through the paper's symbols).
    """
    solver = default_solver() if solver is None else solver
    problem = problem.bounded(data)
    core = _solve(problem, y0, data, solver, max_steps)
    _warn_overflow(core)
    # Sliced and subtracted in NumPy: op by op in JAX, each new length compiles kernels.
    force = np.asarray(core.prediction)
    pred = [force[i, : d.t.shape[0]] for i, d in enumerate(checked)]
    resid = tuple(jnp.asarray(p - np.asarray(d.F)) for p, d in zip(pred, checked))
    pred = tuple(jnp.asarray(p) for p in pred)
    return _assemble(problem, core, pred, resid), core.fit_model


def fit_datasets(
    model,
    datasets: Sequence[Dataset],
    *,
    free: Iterable[str] | None = None,
    props=None,
    solver=None,
    max_steps: int = 256,
    reparameterize: bool = True,
) -> FitResult:
    """Fit `model` to several experiments at once (one residual vector for all of them).

    Each `Dataset` is simulated from the model's zero state at its own first sample. Arguments
    are as for `fit`; `prediction` and `residuals` of the result are tuples, one array per
    dataset. The force scale of the residuals and the metrics (RMSE, NRMSE, R2) are over
    all datasets together.
    """
    if len(datasets) == 0:
        raise ValueError("need at least one dataset")
    checked = [check_dataset(d, where=f"dataset {i}: ") for i, d in enumerate(datasets)]
    problem, y0 = _problem(model, props, free, reparameterize)
    result, _ = _fit_stacked(problem, y0, checked, stack(checked), solver, max_steps)
    return result


def fit(
    model,
    t,
    x,
    F,
    v=None,
    *,
    free: Iterable[str] | None = None,
    props=None,
    solver=None,
    max_steps: int = 256,
    weights=None,
    reparameterize: bool = True,
) -> FitResult:
    """Least-squares fit of any jaxfric model to one experiment.

    **Arguments:**

    - `model`: the starting model (`TwoState`, `GMS`, `LuGre`, `Tustin`, ...); its values are
      the initial guess and the values of held parameters.
    - `t`, `x`, `F`, `v`: times (s), positions (m), measured friction force (N, with the sign
      of the velocity), optional velocities (m/s), 1-D arrays of equal length.
    - `free`: names to fit (leaf names such as ``"Fs"``, ``"l1"``, ``"C"``, ``"nu"``, or groups
      ``"stribeck"``, ``"shape"``); ``None`` uses `props` (default: everything free).
      A `PaperShape` is fitted in `NormalizedPaperShape` coordinates: name ``l1, alpha,
      beta_rel, curvature, quartic`` (or ``"shape"``) there.
    - `props`: a properties pytree (`default_props` of the fit representation) for
      custom transforms, bounds or scales.
    - `solver`: an optimistix least-squares solver or minimiser (default `default_solver`).
    - `max_steps`: iteration limit; reaching it is reported, not raised.
    - `weights`: per-sample weights >= 0 (``None``: all 1).
    - `reparameterize`: fit a `PaperShape` in `NormalizedPaperShape` coordinates (default;
      see `fitting._shape` for why); ``False`` fits ``a, b, c, alpha, beta, l1`` directly.

    **Returns:** a `FitResult`. Failures to converge are reported in ``result``/``status``
    (``throw=False``); shape and value problems of the inputs raise `ValueError`.
    """
    data = Dataset(t=t, x=x, F=F, v=v, weights=weights)
    out = fit_datasets(model, [data], free=free, props=props, solver=solver,
                       max_steps=max_steps, reparameterize=reparameterize)
    return eqx.tree_at(lambda r: (r.prediction, r.residuals), out,
                       (out.prediction[0], out.residuals[0]))


def fit_batch(
    model,
    t,
    x,
    F,
    v=None,
    *,
    weights=None,
    free: Iterable[str] | None = None,
    props=None,
    solver=None,
    max_steps: int = 256,
    reparameterize: bool = True,
    devices: Sequence[jax.Device] | None = None,
    vectorize: bool = False,
) -> FitResult:
    """Fit `model` separately to each of B datasets in one compiled call.

    `t`, `x`, `F`, `v`, `weights` are arrays of shape ``(B, n)``, or sequences of B 1-D arrays
    of different lengths (padded to the longest with weight-0 samples). Every dataset starts
    from the same `model`. Other arguments are as for `fit`.

    **Returns:** a `FitResult` whose arrays have a leading axis B (``result[i]`` is dataset i;
    ``status`` is a list). `prediction` and `residuals` are ``(B, n)`` including any padding
    (whose residuals are meaningless). A dataset that fails (e.g. non-finite forces, or
    `max_steps` reached) reports it in its own ``result``/``status`` and does not change the
    others: each runs its own solver loop. Inputs ``t``, ``x``, ``v`` are checked per
    dataset (``ValueError`` naming the dataset); ``F`` is not, so that one bad dataset
    fails alone.

    `vectorize`: ``False`` (default) solves the datasets one after the other inside the
    compiled call (`jax.lax.map`), each until its own convergence; on a CPU this compiles
    and runs faster than a vmapped solve (`benchmarks/throughput.py` compares both).
    ``True`` vmaps the solver over the datasets (one loop for all, running until the
    slowest dataset stops), for accelerators that gain from the batch.

    `devices`: spread the B datasets over these devices (``jax.devices()`` for all): they
    are split into one contiguous share per device, each share is placed on its device
    and solved there by the same compiled function, and the devices run at once (JAX
    dispatches asynchronously). Nothing is communicated between devices, so one slow
    dataset only holds up its own share. The results equal the one-device results to the
    solver's tolerance (tested with 4 host devices). For several machines, see the README
    ("Many devices and machines").
    """
    count = len(t)
    if count == 0:
        raise ValueError("need at least one dataset")

    def item(a, i):
        return None if a is None else a[i]

    for name, a in (("x", x), ("F", F), ("v", v), ("weights", weights)):
        if a is not None and len(a) != count:
            raise ValueError(f"{name} has {len(a)} datasets, t has {count}")
    checked = [
        check_dataset(
            Dataset(t=t[i], x=x[i], F=F[i], v=item(v, i), weights=item(weights, i)),
            where=f"dataset {i}: ", check_force=False,
        )
        for i in range(count)
    ]
    problem, y0 = _problem(model, props, free, reparameterize)
    solver = default_solver() if solver is None else solver
    stacked = stack(checked)
    # One dataset per fit: (B, 1, n).
    data = jax.tree.map(lambda a: a[:, None, :], stacked)
    problem = problem.bounded(data)
    if devices is not None and len(devices) > 1:
        core = _solve_batch_on_devices(problem, y0, data, solver, max_steps, list(devices),
                                       vectorize)
    else:
        core = _solve_batch(problem, y0, data, solver, max_steps, vectorize)
    _warn_overflow(core)
    pred = np.asarray(core.prediction)[:, 0, :]  # NumPy: see `_fit_stacked`
    return _assemble(problem, core, jnp.asarray(pred),
                     jnp.asarray(pred - np.asarray(stacked.F)))


def _solve_batch_on_devices(problem, y0, data, solver, max_steps, devices, vectorize):
    """`_solve_batch` with the B datasets split into contiguous shares, one per device.

    Each share is placed on its device and solved there by the same compiled function;
    JAX dispatches asynchronously, so the devices work at the same time, and the solver
    loops never wait for one another (a GSPMD-partitioned `vmap` would synchronise every
    iteration of every loop across devices). The last share is padded with copies of its
    last dataset, so that all shares have one shape, and the copies are dropped."""
    count = jax.tree.leaves(data)[0].shape[0]
    share = -(-count // len(devices))
    pending = []
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
        problem_k, y0_k, part = jax.device_put((problem, y0, part), device)
        pending.append((size, _solve_batch(problem_k, y0_k, part, solver, max_steps,
                                           vectorize)))
    shares = [jax.tree.map(lambda a, n=size: np.asarray(a)[:n], out) for size, out in pending]
    return jax.tree.map(lambda *parts: np.concatenate(parts), *shares)
