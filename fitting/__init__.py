"""fitting: parameter identification for jaxfric friction models.

Least-squares fits with optimistix (Levenberg-Marquardt, ``throw=False``) of any jaxfric
model (`TwoState`, `GMS`, `LuGre`, `Tustin`) to measured ``(t, x, F)``, in SI units
(s, m, N; ``F`` with the sign of the velocity). Constraints and free/fixed flags live in a
properties pytree beside the model, never inside it.

**Fitting**

- `fit(model, t, x, F, v=None, *, free=None, props=None, solver=None, max_steps=256,
  weights=None, reparameterize=True, tol=None) -> FitResult`: one experiment; it stops
  when the Gauss-Newton decrease left is a small fraction of the noise variance and holds
  parameters the data do not determine (`Tolerances`, `fitting._stopping`).
- `fit_datasets(model, datasets, ...) -> FitResult`: several experiments (`Dataset`) at once;
  `run_model(model, i)`: the plain model of run i of a fit with per-run parameters.
- `fit_batch(model, t, x, F, v=None, *, weights=None, ...) -> FitResult`: B independent fits
  side by side, each stopping where `fit` would (arrays ``(B, n)``, or ragged lists padded
  with weight-0 samples; one dataset after the other, or vmapped with
  ``vectorize=True``); each dataset gets its
  own result code, and a failing one does not affect the others.
- `fit_staged(model, sliding, presliding=None, lag=None, *, joint=True, ...)
  -> StagedResult`: the paper's Sec. 5 procedure (Stribeck + sigma2 from constant-velocity
  segments, presliding shape from reversals, C from varying-velocity sliding), then a joint
  fit of everything from the staged values.
- `monte_carlo(model, t, x, v=None, *, key, num, param_sigma, noise_sigma, refit=True, ...)
  -> MonteCarloResult`: spread of the predicted force and of refitted parameters.
- `FitResult`: ``model`` (fitted), ``params``/``stderr`` (paper names, SI), ``cov``/``corr``
  (paper parameters), ``cov_fit``/``corr_fit`` (the parameters the solver worked in),
  ``prediction``,
  ``residuals``, ``rmse`` (N), ``nrmse`` (rmse / range of F), ``r2``, ``condition_number``,
  ``result`` (optimistix code), ``status``, ``converged`` (a stopping rule fired, R2 >=
  0.1, no parameter pinned at a bound), ``num_steps``, ``stopped`` (why, in words),
  ``undetermined`` (parameters held because the data do not determine them),
  ``at_bound``, ``summary()``.
  Parameter names: two-state ``Fs, Fc, Vs, delta, sigma2, a, b, c, alpha, beta, l1, C``;
  GMS ``Fs, Fc, Vs, delta, sigma2, C, nu_i, k_i``; LuGre ``Fs, Fc, Vs, delta, sigma0,
  sigma1, sigma2``; Tustin ``Fs, Fc, Vs, delta, sigma2``.

- `initial_model(kind, t, x, F, v=None, *, n_elements=5)`: a starting model of kind
  ``"two-state"``, ``"gms"``, ``"lugre"`` or ``"tustin"`` with scales estimated from the data
  read off the data: the steady-state curve from the steady sliding samples
  (`fitting._steady`), the presliding range from the swing after reversals, an uncertain
  presliding extent and lag settled by simulating a few candidates; what ``jaxfric fit``
  starts from.

- `Tolerances(decrease=0.01, undetermined=1.0, ftol=1e-6, xtol=1e-6, gtol=1e-8)`: when
  a fit is done, passed as ``fit(..., tol=Tolerances(...))``.

**Parameters beside the model**

- `default_props(model, free=None)`: a pytree shaped like the model's parameters holding a
  `ParamProps(transform, free, scale)` per leaf; edit it with ``eqx.tree_at``.
- Transforms: `Identity`, `Exp` (log scale, positive), `Softplus`, `Sigmoid` (bounded),
  `Simplex` (GMS weights). Each leaf is divided by a reference ``scale`` (default: its
  starting value), so values from 1e-9 to 1e15 in SI become coordinates of order one.
- `to_fit_representation(model)`: the model as the solver sees it (a `PaperShape` becomes a
  `NormalizedPaperShape`); custom `props` for `fit` are built on it.
- `natural_params(model)`: ``{name: value}`` in SI with the paper's names.
- `NormalizedPaperShape`: the paper's presliding shape in well-conditioned coordinates
  (``l1, alpha, beta_rel, curvature, quartic``). A `PaperShape` is fitted in these and
  reported back as ``a, b, c, alpha, beta, l1``: ``Pi`` depends on ``a`` and ``c`` only through
  their ratio (an exactly singular direction) and, with the paper's values, on ``a`` and
  ``b`` almost only through ``a*b`` (correlation +-1). `FitResult.corr` shows that
  correlation in the paper's symbols; `FitResult.corr_fit` shows the fit's own.

**Data**

- `Dataset(t, x, F, v=None, weights=None)`; `constant_velocity_segments(t, x, F, v=None)`
  -> `Segments`; `initial_stribeck(segments)`.
- `estimate_velocity(t, x, method="central")`: the velocity a fit of measured data should
  use (zero phase: ``"central"`` or ``"savgol"``; ``"backward"`` is what `jaxfric.simulate`
  derives by itself); `fit(..., v=estimate_velocity(t, x))`.
  `estimate_derivatives(t, x, method)` -> ``(v, a)``, with the acceleration an inertia
  effect reads (``None`` for ``"backward"``): ``fit(..., v=v, a=a)``;
  `estimate_acceleration(t, v)` for a velocity column. `diagnose` does this itself
  (`derivatives=`).

Example::

    import jaxfric, fitting

    start = jaxfric.paper.two_state()              # initial guess (and model structure)
    res = fitting.fit(start, t, x, F, free=["stribeck", "sigma2", "shape", "C"])
    print(res.status, res.rmse)                    # "successful", N
    print(res.summary())                           # values, standard errors
    res.params["l1"], res.stderr["l1"]             # m/N
    staged = fitting.fit_staged(start, fitting.Dataset(t1, x1, F1),
                                fitting.Dataset(t2, x2, F2), fitting.Dataset(t3, x3, F3))
    staged.stages["joint"].params
    batch = fitting.fit_batch(start, t_b, x_b, F_b, free=["Fs", "Fc", "shape"])  # (B, n)
    batch.status[i], batch[i].params                # per dataset
    mc = fitting.monte_carlo(res.model, t, x, key=jax.random.key(0), num=64,
                             param_sigma=res, refit=False)
    mc.force_q05, mc.force_q95                      # prediction band from the fit's covariance

**Compilation.** Each distinct (model structure, data shape, solver, `max_steps`) compiles
once per process: seconds for the first two-state fit or batch on a 2-core CPU (see
docs/validation.md and `benchmarks/profiling/fit_compile.py`), less for Tustin/LuGre/GMS; further
calls with the same shapes run in well under a second to a few seconds. Changing the free
set, the starting values or the weights does not recompile (see `fitting._problem`); data
whose number of reversals falls in another power-of-two bucket (up to 64, 128, 256, ...)
does, as the two-state simulation sizes its list of reversals by it.
"""
# The fit's shape coordinates are a shape family of the core, re-exported here.
from jaxfric import NormalizedPaperShape as NormalizedPaperShape

from ._candidates import Candidate as Candidate
from ._data import Dataset as Dataset
from ._derivatives import (
    estimate_acceleration as estimate_acceleration,
    estimate_derivatives as estimate_derivatives,
    estimate_velocity as estimate_velocity,
)
from ._diagnose import diagnose as diagnose
from ._diagnosis import Diagnosis as Diagnosis
from ._fit import fit as fit, fit_batch as fit_batch, fit_datasets as fit_datasets
from ._montecarlo import monte_carlo as monte_carlo, MonteCarloResult as MonteCarloResult
from ._params import (
    default_props as default_props,
    natural_params as natural_params,
    to_fit_representation as to_fit_representation,
)
from ._per_run import run_model as run_model
from ._regimes import regime_errors as regime_errors, regimes as regimes
from ._result import FitResult as FitResult
from ._rules import DiagnosisRules as DiagnosisRules
from ._solve import default_solver as default_solver, geodesic_solver as geodesic_solver
from ._staged import (
    constant_velocity_segments as constant_velocity_segments,
    fit_staged as fit_staged,
    initial_stribeck as initial_stribeck,
    Segments as Segments,
    StagedResult as StagedResult,
)
from ._start import initial_model as initial_model
from ._stopping import Tolerances as Tolerances
from ._transforms import (
    AbstractTransform as AbstractTransform,
    Exp as Exp,
    Identity as Identity,
    ParamProps as ParamProps,
    Sigmoid as Sigmoid,
    Simplex as Simplex,
    Softplus as Softplus,
)
