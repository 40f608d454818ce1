"""Least-squares fits of any jaxfric model to measured ``(t, x, F)``.

**Solver.** Levenberg-Marquardt with geodesic acceleration by default
(`fitting._solve.default_solver`, `fitting._geodesic`, with MINPACK's trust-region
update), because:

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
  does not square the condition number the way the normal equations would;
- in the curved valleys these models have (the presliding shape, Fc ~ Vs), geodesic
  acceleration, one more residual evaluation per step, keeps long steps on the valley's
  floor; its Jacobian, materialised once per accepted point, makes up for the evaluation.

`optimistix.LevenbergMarquardt`, `optimistix.Dogleg` or
`optimistix.IndirectLevenbergMarquardt` can be passed as ``solver`` instead; any optimistix
minimiser also works (it minimises the sum of squares).

**Compilation.** The free set is a traced mask (`fitting._problem`), `lax.map` loops over the
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
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import jaxfric

from ._blas import single_threaded_blas
from ._chunked import solve_chunked, solve_chunked_batch
from ._data import absurd_sample, check_dataset, Dataset, stack
from ._gc import paused_gc
from ._per_run import has_per_run, run_model, shifted, with_runs
from ._problem import _Problem, _problem
from ._result import _assemble, _warn_overflow, final_stop, FitResult
from ._solve import (
    _solve,
    _solve_batch,
    _solve_batch_on_devices,
    default_solver,
    device_shares,
    join_shares,
    MIN_R2,
)
from ._stopping import Tolerances


def _fit_stacked(problem: _Problem, y0, checked: Sequence[Dataset], data: Dataset, solver,
                 max_steps: int, tol: Tolerances | None = None, progress=None):
    """Solve for checked datasets stacked (and possibly re-weighted) into `data`.

    Returns the `FitResult` (per-dataset `prediction`/`residuals` tuples, padding removed)
    and the fitted model in the fit representation (to chain stages without a round trip
    through the paper's symbols).
    """
    solver = default_solver() if solver is None else solver
    problem = problem.bounded(data)
    undetermined: tuple[str, ...] = ()
    kind = None
    # (fitting._blas: OpenBLAS's spinning threads; fitting._gc: Python's cyclic collector)
    with single_threaded_blas(), paused_gc():
        if isinstance(solver, optx.AbstractLeastSquaresSolver):
            solved = solve_chunked(problem, y0, data, solver, max_steps,
                                   tol or Tolerances(), progress)
            core, stopped, problem = solved.core, solved.stopped, solved.problem
            undetermined, kind = solved.undetermined, solved.stop
        else:  # a minimiser: one compiled loop (no Jacobian to scale by)
            core, stopped = _solve(problem, y0, data, solver, max_steps), ""
    stopped = _honest(core, stopped, problem)
    stop = _stop(core, problem, kind)
    _warn_overflow(core)
    # Sliced and subtracted in NumPy: op by op in JAX, each new length compiles kernels.
    force = np.asarray(core.prediction)
    pred = [force[i, : d.t.shape[0]] for i, d in enumerate(checked)]
    resid = tuple(jnp.asarray(p - np.asarray(d.F)) for p, d in zip(pred, checked))
    pred = tuple(jnp.asarray(p) for p in pred)
    return (_assemble(problem, core, pred, resid, stopped, undetermined, stop),
            core.fit_model)


def _failed_checks(r2, at_bound, names) -> tuple[bool, list[str]]:
    """Whether a fit of R2 `r2` and flags `at_bound` (per leaf of `names`) fails `fit`'s
    checks (`fitting._solve._finish_impl`: R2 below `MIN_R2`, a parameter pinned at a
    bound of its transform), and the names of the pinned ones."""
    bound = [n for n, b in zip(names, np.asarray(at_bound)) if b]
    return float(r2) < MIN_R2 or bool(bound), bound


def _stop(core, problem: _Problem, kind: str | None, i=None) -> str:
    """The `FitResult.stop` of one fit (dataset `i` of a batched `core`): `kind` as the
    chunked solve decided it (``None`` for a minimiser's single loop, judged by its result
    code), with `fit`'s checks (`fitting._result.final_stop`)."""
    pick = (lambda a: a) if i is None else (lambda a: np.asarray(a)[i])
    code = jax.tree.map(pick, core.result)
    failed, _ = _failed_checks(pick(core.r2), pick(core.at_bound), problem.layout.names)
    if kind is None:  # (a minimiser's loop stuck at its start ends in nonlinear_divergence)
        if code == optx.RESULTS.nonlinear_max_steps_reached:
            kind = "max_steps"
        elif code == optx.RESULTS.nonlinear_divergence and not failed:
            kind = "stuck"
        else:
            kind = "converged" if code in (optx.RESULTS.successful,
                                           optx.RESULTS.nonlinear_divergence) else "failed"
    return final_stop(kind, code, failed)


def _honest(core, stopped: str, problem: _Problem) -> str:
    """`stopped` with the reason a fit whose stopping rule fired is still not converged
    (`fitting._solve._finish_impl`: R2 below `MIN_R2`, a parameter pinned at a bound)."""
    _, bound = _failed_checks(core.r2, core.at_bound, problem.layout.names)
    why = []
    if float(core.r2) < MIN_R2:
        why.append(f"R2 = {float(core.r2):.3g} < {MIN_R2:g}: the data are not explained")
    if bound:
        why.append(f"pinned at a bound of its transform: {', '.join(bound)}")
    if why and stopped:
        stopped += "; NOT converged: " + "; ".join(why)
    return stopped


def fit_datasets(
    model,
    datasets: Sequence[Dataset],
    *,
    free: Iterable[str] | None = None,
    props=None,
    solver=None,
    max_steps: int = 256,
    reparameterize: bool = True,
    tol: Tolerances | None = None,
    progress=None,
    narrow: bool = False,
) -> FitResult:
    """Fit `model` to several experiments at once (one residual vector for all of them).

    Each `Dataset` is simulated from the model's zero state at its own first sample. Arguments
    are as for `fit`; `prediction` and `residuals` of the result are tuples, one array per
    dataset. The force scale of the residuals and the metrics (RMSE, NRMSE, R2) are over
    all datasets together. A dataset's `known` force is subtracted from its `F` before the
    fit (`prediction` is the model's force alone; `residuals` is ``prediction + known - F``).

    Parameters declared ``per_run`` on an effect (`jaxfric._fields.param`: the offset of
    `jaxfric.effects.Offset`) get one value per dataset when there are two or more
    (`fitting._per_run`): ``params`` names them ``offset_1 .. offset_D`` in dataset order,
    `fitting.run_model` gives the plain model of one dataset (and, with ``None``, the mean
    model for data not fitted); every other parameter is shared. One declared
    ``per_run="relative"`` (`jaxfric.effects.Drift`'s ``drift_level``) keeps dataset 1's
    value and is fitted for the others (``drift_level_2 .. drift_level_D``); with one
    dataset it is held.

    `narrow`: compute the Jacobian over the free coordinates only when most are held
    (`fitting._problem._Problem.narrowed`; the same fit, faster, one compilation per
    width), as the diagnosis does with its superset of effects.
    """
    if len(datasets) == 0:
        raise ValueError("need at least one dataset")
    checked = [_without_known(check_dataset(d, where=f"dataset {i}: "))
               for i, d in enumerate(datasets)]
    per_run = len(checked) > 1 and has_per_run(model)
    if per_run and props is not None:
        raise ValueError("props= with per-run parameters: set free= instead")
    model = with_runs(model, len(checked))
    solved = shifted(checked) if per_run else checked
    problem, y0 = _problem(model, props, free, reparameterize)
    if narrow:
        problem = problem.narrowed()
    result, _ = _fit_stacked(problem, y0, solved, stack(solved), solver, max_steps, tol,
                             progress)
    return _as_simulated(result, checked)


def _without_known(d: Dataset) -> Dataset:
    """`d` (checked) with its known force subtracted from `F` (samples of weight 0 stay 0)."""
    if d.known is None:
        return d
    return dataclasses.replace(d, F=np.where(d.weights > 0, d.F - d.known, 0.0), known=None)


def _as_simulated(result: FitResult, checked: Sequence[Dataset]) -> FitResult:
    """`result` with `prediction` and `residuals` recomputed by `jaxfric.simulate` on its
    `fit_model`, the model a result's JSON saves: the compiled solve evaluates the same
    model fused into its own program, which can differ in the last bits (about 1e-15 N), and
    a saved fit must reproduce its prediction bit for bit (`simulate --params`). A model
    with values that are not finite (a diverged fit) keeps the solve's prediction."""
    if not _finite(result.fit_model):
        return result
    pred = tuple(jaxfric.simulate(run_model(result.fit_model, i), d.t, d.x, d.v, load=d.load,
                                  a=d.a)
                 for i, d in enumerate(checked))
    resid = tuple(jnp.asarray(np.asarray(p) - np.asarray(d.F)) for p, d in zip(pred, checked))
    return eqx.tree_at(lambda r: (r.prediction, r.residuals), result, (pred, resid))


def _finite(model) -> bool:
    leaves = jax.tree_util.tree_leaves(eqx.filter(model, eqx.is_inexact_array))
    return all(bool(jnp.all(jnp.isfinite(leaf))) for leaf in leaves)


def _batch_as_simulated(result: FitResult, checked: Sequence[Dataset], F) -> FitResult:
    """`_as_simulated` for `fit_batch`: dataset i's prediction (its first samples, padding
    kept) is `jaxfric.simulate` of its own `fit_model` on its own (unpadded) data, what
    ``simulate(load_model(saved JSON), t_i, x_i, v_i)`` gives; `F` is the stacked force."""
    pred = np.array(result.prediction)
    for i, d in enumerate(checked):
        model = jax.tree.map(lambda a, i=i: a[i], result.fit_model)
        if _finite(model):
            pred[i, : d.t.shape[0]] = np.asarray(jaxfric.simulate(model, d.t, d.x, d.v,
                                                                  a=d.a))
    return eqx.tree_at(lambda r: (r.prediction, r.residuals), result,
                       (jnp.asarray(pred), jnp.asarray(pred - np.asarray(F))))


def _without_glitches(d: Dataset, i: int) -> Dataset:
    """`d` with an absurd force sample (`absurd_sample`) made NaN, with a warning: the
    dataset then fails alone (not ``successful``), as for a non-finite force, instead of
    reporting success at its start values."""
    found = absurd_sample("F", d.F, d.weights)
    if found is None:
        return d
    k, why = found
    warnings.warn(f"dataset {i}: {why}; this dataset is not fitted (its status says so)",
                  jaxfric.data.DataWarning, stacklevel=3)
    F = np.array(d.F)
    F[k] = np.nan
    return dataclasses.replace(d, F=F)


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
    tol: Tolerances | None = None,
    progress=None,
    load=None,
    a=None,
    known=None,
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
    - `tol`: when the fit is done, a `Tolerances` (default ``Tolerances()``): chiefly,
      when the Gauss-Newton decrease of the cost left is a small fraction of the noise
      variance (`fitting._stopping`), tested after every step; parameters the data do not
      determine are held at their start (``result.undetermined``). Neither `tol` nor
      `max_steps` recompiles: a second fit of the same shapes reuses the compiled solver.
      Why the fit stopped is in ``result.stopped``. Converged means a stopping rule fired,
      R2 >= `fitting._solve.MIN_R2` and no parameter is pinned at a bound of its transform.
    - `progress`: called after every compiled chunk of steps (about a second each) with
      ``.steps``, ``.cost`` and ``.seconds``; Ctrl-C stops the fit between chunks.
    - `weights`: per-sample weights >= 0 (``None``: all 1).
    - `reparameterize`: fit a `PaperShape` in `NormalizedPaperShape` coordinates (default;
      see `jaxfric.NormalizedPaperShape` for why); ``False`` fits ``a, b, c, alpha, beta,
      l1`` directly.
    - `load`: the transmitted load (N, or N m), for a model with
      `jaxfric.effects.LoadFriction` (``jaxfric.simulate(..., load=...)``).
    - `a`: the acceleration (m/s^2) that `jaxfric.effects.Inertia` reads (``None``: the
      backward difference of `v`, as `jaxfric.simulate`); for measured data a zero-phase
      estimate, `estimate_derivatives`, or a measured column.
    - `known`: a known force component in `F` (N: an external force applied on purpose, a
      model part already identified), subtracted from `F` and not fitted; `prediction`
      is then the model's force alone.

    **Returns:** a `FitResult`. Failures to converge are reported in ``result``/``status``
    (``throw=False``); shape and value problems of the inputs raise `ValueError`.
    """
    data = Dataset(t=t, x=x, F=F, v=v, weights=weights, load=load, a=a, known=known)
    out = fit_datasets(model, [data], free=free, props=props, solver=solver,
                       max_steps=max_steps, reparameterize=reparameterize, tol=tol,
                       progress=progress)
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
    a=None,
    tol: Tolerances | None = None,
) -> FitResult:
    """Fit `model` separately to each of B datasets, all of them in each compiled call.

    `t`, `x`, `F`, `v`, `weights`, `a` (the acceleration, as for `fit`) are arrays of shape
    ``(B, n)``, or sequences of B 1-D arrays of different lengths (padded to the longest
    with weight-0 samples). Every dataset starts
    from the same `model`. Other arguments are as for `fit`, and each dataset stops where
    `fit` would stop on it: the same compiled chunks, column scaling and stopping rules
    (`tol`), run for every dataset not yet done in one compiled call per round
    (`fitting._chunked.solve_chunked_batch`); undetermined parameters are not held (the
    problem is shared by the batch).

    **Returns:** a `FitResult` whose arrays have a leading axis B (``result[i]`` is dataset i;
    ``status`` is a list). `prediction` and `residuals` are ``(B, n)`` including any padding
    (whose residuals are meaningless). A dataset that fails (e.g. non-finite forces, or
    `max_steps` reached) reports it in its own ``result``/``status`` and does not change the
    others: each runs its own solver loop. Inputs ``t``, ``x``, ``v`` are checked per
    dataset (``ValueError`` naming the dataset); ``F`` is not, so that one bad dataset
    fails alone: a non-finite or absurd force (`fitting._data.absurd_sample`; a
    `jaxfric.data.DataWarning` names it) leaves that dataset's status not successful.
    Dataset i's prediction is `jaxfric.simulate` of its own ``fit_model`` on its data, so
    the model saved from ``result[i]`` reproduces it bit for bit.

    `vectorize`: ``False`` (default) runs each round's chunks one dataset after the other
    inside the compiled call (`jax.lax.map`), each until its own stopping rule; on a CPU
    this compiles and runs faster than a vmapped solve (`benchmarks/throughput.py`
    compares both). ``True`` vmaps each round's chunks over the datasets (one loop for
    all, running until the slowest dataset's chunk ends), for accelerators that gain from
    the batch.

    `devices`: spread the B datasets over these devices (``jax.devices()`` for all): they
    are split into one contiguous share per device, each share is placed on its device
    and solved there, in its own thread, by the same compiled functions, so the devices
    run at once. Nothing is communicated between devices, so one slow dataset only holds
    up its own share. The results equal the one-device results to the
    solver's tolerance (tested with 4 host devices). For several machines, see the README
    ("Many devices and machines").
    """
    count = len(t)
    if count == 0:
        raise ValueError("need at least one dataset")

    def item(a, i):
        return None if a is None else a[i]

    for name, arr in (("x", x), ("F", F), ("v", v), ("weights", weights), ("a", a)):
        if arr is not None and len(arr) != count:
            raise ValueError(f"{name} has {len(arr)} datasets, t has {count}")
    checked = [
        check_dataset(
            Dataset(t=t[i], x=x[i], F=F[i], v=item(v, i), weights=item(weights, i),
                    a=item(a, i)),
            where=f"dataset {i}: ", check_force=False,
        )
        for i in range(count)
    ]
    for i, d in enumerate(checked):  # a loop: the warning points at the caller
        checked[i] = _without_glitches(d, i)
    problem, y0 = _problem(model, props, free, reparameterize)
    solver = default_solver() if solver is None else solver
    stacked = stack(checked)
    # One dataset per fit: (B, 1, n).
    data = jax.tree.map(lambda a: a[:, None, :], stacked)
    problem = problem.bounded(data)
    tol = Tolerances() if tol is None else tol
    rule = (jnp.asarray(tol.decrease, float), jnp.asarray(tol.undetermined, float))
    with single_threaded_blas(), paused_gc():  # (fitting._blas, fitting._gc)
        if isinstance(solver, optx.AbstractLeastSquaresSolver):
            core, kinds = _chunked_on_devices(problem, y0, data, solver, max_steps, tol,
                                              vectorize, devices)
        elif devices is not None and len(devices) > 1:
            core = _solve_batch_on_devices(problem, y0, data, solver, max_steps,
                                           list(devices), vectorize, *rule)
            kinds = [None] * count
        else:
            core = _solve_batch(problem, y0, data, solver, max_steps, vectorize, *rule)
            kinds = [None] * count
    _warn_overflow(core)
    pred = np.asarray(core.prediction)[:, 0, :]  # NumPy: see `_fit_stacked`
    stop = tuple(_stop(core, problem, kind, i) for i, kind in enumerate(kinds))
    result = _assemble(problem, core, jnp.asarray(pred),
                       jnp.asarray(pred - np.asarray(stacked.F)), stop=stop)
    return _batch_as_simulated(result, checked, stacked.F)


def _chunked_on_devices(problem: _Problem, y0, data: Dataset, solver, max_steps: int,
                        tol: Tolerances, vectorize: bool, devices):
    """`solve_chunked_batch` of the B datasets of `data`, split into contiguous shares,
    one per device (`device_shares`), each share placed on its device and solved there in
    its own thread (the loops between chunks are Python; the devices compute at once).
    Returns the batched core and each dataset's kind of stop (`Solved.stop`)."""
    if devices is None or len(devices) <= 1:
        core, _, kinds = solve_chunked_batch(problem, y0, data, solver, max_steps, tol,
                                             vectorize)
        return core, kinds
    parts = [(size, jax.device_put((problem, y0, part), device))
             for size, part, device in device_shares(data, devices)]
    with ThreadPoolExecutor(len(parts)) as pool:
        jobs = [(size, pool.submit(solve_chunked_batch, *placed, solver, max_steps, tol,
                                   vectorize)) for size, placed in parts]
        done = [(size, job.result()) for size, job in jobs]
        return (join_shares([(size, out[0]) for size, out in done]),
                [kind for size, out in done for kind in out[2][:size]])
