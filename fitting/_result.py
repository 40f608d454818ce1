"""The outcome of a fit: `FitResult` (values, standard errors, correlations, metrics,
the result code), assembled from the arrays of the compiled solve.
"""

import dataclasses
import warnings
from typing import Any

import equinox as eqx
import jax
import numpy as np
import optimistix as optx
from jaxtyping import Array

import jaxfric

from . import _params
from ._problem import _Problem
from ._solve import _Core


#: Result codes by name (`optimistix.RESULTS` includes lineax's).
_RESULT_NAMES = ("successful", "nonlinear_max_steps_reached", "nonlinear_divergence",
                 "nonfinite", "max_steps_reached", "singular", "breakdown", "stagnation",
                 "conlim", "nonfinite_input")

#: Correlation (in magnitude) above which two fitted parameters are reported as weakly
#: determined (`FitResult.weakly_determined`).
WEAK_CORRELATION = 0.99

#: The kinds of stop (`FitResult.stop`), decided where the fit stops (`fitting._chunked`,
#: `fitting._fit` for the checks): ``"converged"`` (a stopping rule fired and the fit
#: passes `fit`'s checks), ``"kink"`` (the steps gain nothing while the Gauss-Newton model
#: still predicts more than chance: a kink of the cost; no certificate of a minimum, so
#: `converged` is False), ``"stuck"`` (no step moves the fit or lowers the cost although
#: the gradient is not nil), ``"max_steps"`` (cut at the step limit), ``"failed"`` (the
#: solver failed, or the cost is not finite), ``"checks"`` (a rule fired, converged or at a
#: kink, but the fit fails `fit`'s checks: R2 below `fitting._solve.MIN_R2`, a parameter
#: pinned at a bound).
STOPS = ("converged", "kink", "stuck", "max_steps", "failed", "checks")


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
    - `fit_model`: the fitted model as the solver built it (a `PaperShape` as the
      equivalent `NormalizedPaperShape`): the model whose simulation is `prediction`,
      finite where the paper's ``a`` overflows; what `jaxfric.save_model` should keep.
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
    - `stopped`: why the fit stopped, in words (which stopping rule of
      `fitting._stopping.Tolerances` fired, or the step limit, and why a fit whose rule
      fired is still not converged); empty for `fit_batch`.
    - `stop`: the kind of stop, one of `STOPS` (a tuple, one per dataset, for `fit_batch`).
    - `undetermined`: names (of `fit_names`) of the parameters the data do not determine
      (standard error above `Tolerances.undetermined` in the solver's coordinates: not
      even a factor e for a positive parameter). `fit` holds them at their start values;
      their standard errors, and those of paper parameters derived from them, are NaN.
      Empty for `fit_batch`.
    - `at_bound`: one flag per parameter leaf (`leaf_names`): free and pinned at a bound of
      its transform (`fitting._transforms.PINNED`), e.g. ``Fs`` collapsed to 1e-9 N.

    Weakly determined directions are reported, not iterated on: `weakly_determined` lists
    the pairs of fitted parameters (of the solver's representation) whose correlation
    exceeds `WEAK_CORRELATION` in magnitude, and `summary` prints them with the condition
    number. The data fix such a pair's combination but hardly each one alone; the stopping
    rules end the fit once the cost stops falling, not once these directions settle.

    Properties: `converged` (result is successful: a stopping rule fired, R2 is at least
    `fitting._solve.MIN_R2` and no parameter is pinned at a bound), `status` (the code's
    name).
    """

    model: Any
    fit_model: Any
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
    at_bound: Array | None = None
    leaf_names: tuple[str, ...] = eqx.field(static=True, default=())
    stopped: str = eqx.field(static=True, default="")
    undetermined: tuple[str, ...] = eqx.field(static=True, default=())
    stop: str | tuple[str, ...] = eqx.field(static=True, default="")

    @property
    def converged(self) -> Array:
        return self.result == optx.RESULTS.successful

    @property
    def status(self) -> str | list[str]:
        return status_name(self.result)

    def __getitem__(self, i) -> "FitResult":
        """Dataset `i` of a batched result (from `fit_batch`)."""
        out = jax.tree.map(lambda a: a[i], self)
        if isinstance(self.stop, tuple):
            out = dataclasses.replace(out, stop=self.stop[i])
        return out

    def weakly_determined(self, threshold: float | None = None) -> list[tuple[str, str, float]]:
        """``(name, name, correlation)`` of the free fitted parameters (`fit_names`) whose
        correlation is above `threshold` (default `WEAK_CORRELATION`) in magnitude,
        strongest first (one fit; for a batch use ``result[i]``)."""
        threshold = WEAK_CORRELATION if threshold is None else threshold
        corr = np.asarray(self.corr_fit)
        free = set(self.free)
        idx = [i for i, n in enumerate(self.fit_names) if n in free]
        pairs = [(self.fit_names[i], self.fit_names[j], float(corr[i, j]))
                 for k, i in enumerate(idx) for j in idx[k + 1:]
                 if np.isfinite(corr[i, j]) and abs(corr[i, j]) > threshold]
        return sorted(pairs, key=lambda p: -abs(p[2]))

    def summary(self) -> str:
        """A plain-text table: name, value, standard error, relative error (one fit; for
        a batch use ``result[i].summary()``)."""
        head = (f"status: {self.status}   steps: {int(self.num_steps)}   "
                f"RMSE: {float(self.rmse):.4g} N   NRMSE: {float(self.nrmse):.4g}   "
                f"R2: {float(self.r2):.6f}")
        lines = [head] + ([f"stopped: {self.stopped}"] if self.stopped else [])
        if self.undetermined:
            lines.append(f"undetermined by the data (no standard error; see 'stopped' for "
                         f"whether held): {', '.join(self.undetermined)}")
        for name in self.names:
            v, s = float(self.params[name]), float(self.stderr[name])
            rel = f"{100 * s / abs(v):9.3g} %" if v != 0 else ""
            lines.append(f"  {name:>10s} = {v: .6e}  +- {s:.2e} {rel}")
        return "\n".join(lines + weak_lines(self))


def weak_lines(res: FitResult) -> list[str]:
    """The weakly determined pairs of `res` in words (nothing when there are none)."""
    pairs = res.weakly_determined()
    if not pairs:
        return []
    out = [f"weakly determined (|correlation| > {WEAK_CORRELATION}; condition number "
           f"{float(res.condition_number):.3g}): the data fix these combinations, not each "
           "parameter alone:"]
    return out + [f"  {a} ~ {b}: correlation {c:+.4f}" for a, b, c in pairs]


#: The paper's shape parameters, all derived from the fitted `NormalizedPaperShape`.
_PAPER_SHAPE = ("a", "b", "c", "alpha", "beta", "l1")
_NORMALIZED_SHAPE = ("l1", "alpha", "beta_rel", "curvature", "quartic")


def _unknown_errors(names, undetermined, paper_shape: bool) -> set[str]:
    """The reported parameters whose standard error is unknown: the undetermined ones and,
    for a reparameterised `PaperShape`, every paper shape parameter if a normalised shape
    parameter is undetermined (each is derived from all of them)."""
    out = set(undetermined) & set(names)
    if paper_shape and set(undetermined) & set(_NORMALIZED_SHAPE):
        out |= set(_PAPER_SHAPE) & set(names)
    return out


def _assemble(problem: _Problem, core: _Core, prediction, residuals,
              stopped: str = "", undetermined: tuple[str, ...] = (),
              stop: str | tuple[str, ...] = "") -> FitResult:
    """Turn solver arrays into a `FitResult` (works on batched cores too)."""
    layout = problem.layout
    batched = core.y.ndim == 2

    def first(model):  # names and structure do not depend on the values
        return jax.tree.map(lambda a: np.asarray(a)[0], model) if batched else model

    names = _params.natural_names(first(core.model))
    leaf_free = np.asarray(layout.leaf_free)
    unknown = _unknown_errors(names, undetermined, problem.paper_shape)
    stderr = [np.nan if n in unknown else s for n, s in zip(names, core.stderr)]
    return FitResult(
        model=core.model,
        fit_model=core.fit_model,
        params=dict(zip(names, core.params)),
        stderr=dict(zip(names, stderr)),
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
        at_bound=core.at_bound,
        leaf_names=layout.names,
        stopped=stopped,
        undetermined=tuple(undetermined),
        stop=stop,
    )


def final_stop(kind: str, result, checks_failed: bool) -> str:
    """The `STOPS` kind of a fit whose solve stopped by `kind` (``"converged"``,
    ``"kink"``, ``"stuck"``, ``"max_steps"`` or ``"failed"``, as the chunked solve decided)
    and ended with the result code `result` (after `fitting._solve._finish_impl`'s checks):
    a successful code is converged (a solve cut at its step limit at the optimum, too);
    a non-finite fit failed; a rule that fired on a fit failing the checks is "checks"."""
    if bool(np.asarray(result == optx.RESULTS.successful)):
        return "converged"
    if bool(np.asarray(result == optx.RESULTS.nonfinite)):
        return "failed"
    if kind in ("converged", "kink") and checks_failed:
        return "checks"
    return "failed" if kind == "converged" else kind


def _warn_overflow(core: _Core) -> None:
    total = int(np.sum(np.asarray(core.overflow)))
    if total > 0:
        warnings.warn(
            f"the fitted model's memory stack overflowed {total} time(s) on the data; "
            "increase the model's stack_size",
            jaxfric.StackOverflowWarning,
            stacklevel=3,
        )


def saved_model(model) -> dict | None:
    """`model` as `jaxfric.model_to_dict` writes it for a result's JSON (exact, reloadable
    with `jaxfric.load_model`), or None if a value is not finite (a diverged fit)."""
    try:
        return jaxfric.model_to_dict(model)
    except ValueError:
        return None
