"""Monte-Carlo sensitivity: perturbed parameters and/or noise, predicted force and refits.

Draws are made in the solver's coordinates ``y`` (see `_transforms`): for an `Exp` leaf a
standard deviation ``sigma`` there is a relative (log-normal) spread of about ``sigma`` in
the parameter, for `Identity` a spread of ``sigma*|p0|``, for `Sigmoid`/`Simplex` a spread of
the logit/log-ratio. Drawing from a `FitResult`'s covariance instead gives the prediction
band that the fit's own uncertainty implies.
"""

from collections.abc import Iterable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, PRNGKeyArray

from jaxfric._compile import jit

from . import _params
from ._data import check_dataset, Dataset, stack
from ._fit import fit_batch
from ._problem import _Problem, _problem, _simulate_stack
from ._result import FitResult


class MonteCarloResult(eqx.Module):
    """The outcome of `monte_carlo` (arrays over ``num`` draws and/or samples).

    - `force`: ``(num, n)`` model force of every perturbed model along the motion (N, no
      noise); `force_mean`, `force_std`, `force_q05`, `force_q95` over the draws.
    - `true_params`: ``{name: (num,)}`` the perturbed models' parameters (SI).
    - `fits`: the batched `FitResult` of the refits (``None`` without `refit`).
    - `param_mean`, `param_std`: ``{name: value}`` over the *converged* refits: the spread
      says which parameters the data determine (compare with the fits' `stderr`).
    - `converged_fraction`: share of refits that converged.
    """

    force: Array
    force_mean: Array
    force_std: Array
    force_q05: Array
    force_q95: Array
    true_params: dict[str, Array]
    fits: FitResult | None
    param_mean: dict[str, Array] | None
    param_std: dict[str, Array] | None
    converged_fraction: Array | None


@jit
def _predict(problem: _Problem, ys: Array, data: Dataset):
    def one(y):
        force, _ = _simulate_stack(problem.model(y), data, problem.max_reversals)
        return force[0], _params.natural_vector(problem.user_model(y))

    return jax.vmap(one)(ys)


def _draws(key, problem, y0, num, param_sigma):
    """``(num, p)`` perturbed coordinate vectors around ``y0``."""
    layout = problem.layout
    mask = layout.coordinate_mask()
    p = y0.shape[0]
    eps = jax.random.normal(key, (num, p), dtype=y0.dtype)
    if isinstance(param_sigma, FitResult):
        # Correlated draws from the fit's covariance: map cov(p) of the fit
        # representation's parameters to y to first order, cov(y) = K cov(p) K^T.
        template = problem.template
        names = _params.natural_names(template)
        if names != param_sigma.fit_names:
            raise ValueError(f"the FitResult is for parameters {param_sigma.fit_names}, the "
                             f"model has {names}: pass model=result.model")
        p0 = _params.natural_vector(template)

        def to_y(p):
            return _params.to_vector(_params.from_natural_vector(p, template), layout)

        k = jax.jacfwd(to_y)(p0)
        cov = k @ jnp.nan_to_num(param_sigma.cov_fit) @ k.T
        w, vec = jnp.linalg.eigh(0.5 * (cov + cov.T))
        root = vec * jnp.sqrt(jnp.maximum(w, 0.0))
        return y0 + eps @ root.T
    if isinstance(param_sigma, dict):
        sig = []
        for name, size in zip(layout.names, layout.sizes):
            sig.extend([float(param_sigma.get(name, 0.0))] * size)
        unknown = set(param_sigma) - set(layout.names)
        if unknown:
            raise ValueError(f"param_sigma names {sorted(unknown)} are not parameters of the "
                             f"model; its parameters are {list(layout.names)}")
        sigma = jnp.asarray(sig, dtype=y0.dtype)
    else:
        sigma = jnp.full((p,), float(param_sigma), dtype=y0.dtype)
    return y0 + eps * sigma * mask


def monte_carlo(
    model,
    t,
    x,
    v=None,
    *,
    key: PRNGKeyArray,
    num: int = 32,
    param_sigma: float | dict[str, float] | FitResult = 0.0,
    noise_sigma: float = 0.0,
    refit: bool = True,
    free: Iterable[str] | None = None,
    props=None,
    solver=None,
    max_steps: int = 256,
    reparameterize: bool = True,
    devices=None,
) -> MonteCarloResult:
    """Monte-Carlo sensitivity of a model along one motion, vectorised with `jax.vmap`.

    Each of `num` draws perturbs the free parameters of `model` (`param_sigma`), simulates
    the force along ``(t, x[, v])``, adds Gaussian noise of standard deviation `noise_sigma`
    (N), and (with `refit`) fits `model` back to that synthetic measurement, all draws in one
    compiled solve (`fit_batch`).

    **Arguments:**

    - `model`, `t`, `x`, `v`: the nominal model and the motion (s, m, m/s).
    - `key`: a `jax.random` key.
    - `num`: number of draws.
    - `param_sigma`: standard deviation of the perturbation in fit coordinates (module
      docstring): one float for all free parameters, ``{name: sigma}`` per leaf, or a
      `FitResult` to draw from its covariance (``model`` should then be ``result.model``).
    - `noise_sigma`: measurement noise added before refitting, N.
    - `refit`, `free`, `props`, `solver`, `max_steps`, `reparameterize`: as for `fit`; `free`
      selects both what is perturbed and what is refitted.
    - `devices`: shard the refits over these devices (see `fit_batch`).

    With ``param_sigma=0`` and ``noise_sigma > 0`` this is a parametric bootstrap: the refit
    spread should match the standard errors of a fit (`FitResult.stderr`).
    """
    if num < 1:
        raise ValueError(f"num must be >= 1, got {num}")
    data = check_dataset(Dataset(t=t, x=x, F=np.zeros(np.shape(t)), v=v))
    problem, y0 = _problem(model, props, free, reparameterize)
    key_p, key_n = jax.random.split(key)
    ys = _draws(key_p, problem, y0, num, param_sigma)
    stacked = stack([data])
    force, natural = _predict(problem.bounded(stacked), ys, stacked)
    names = _params.natural_names(problem.user_model(y0))
    noisy = force + noise_sigma * jax.random.normal(key_n, force.shape, dtype=force.dtype)

    fits = mean = std = frac = None
    if refit:

        def tile(a):
            return None if a is None else np.broadcast_to(a, (num, *a.shape))

        fits = fit_batch(
            model, tile(data.t), tile(data.x), np.asarray(noisy), tile(data.v),
            free=free, props=props, solver=solver, max_steps=max_steps,
            reparameterize=reparameterize, devices=devices,
        )
        ok = np.asarray(fits.converged)
        frac = jnp.asarray(ok.mean())
        mean = {n: jnp.mean(fits.params[n][ok]) for n in names}
        std = {n: jnp.std(fits.params[n][ok], ddof=1) if ok.sum() > 1 else jnp.nan
               for n in names}
    return MonteCarloResult(
        force=force,
        force_mean=jnp.mean(force, axis=0),
        force_std=jnp.std(force, axis=0),
        force_q05=jnp.quantile(force, 0.05, axis=0),
        force_q95=jnp.quantile(force, 0.95, axis=0),
        true_params={n: natural[:, i] for i, n in enumerate(names)},
        fits=fits,
        param_mean=mean,
        param_std=std,
        converged_fraction=frac,
    )
