"""Worked example: every jaxfric model fitted to a real reciprocating-tribometer record.

    python examples/tribometer.py [--data PATH] [--json OUT.json] [--out DIR] [--quick]

**Data.** A CSV with a header row and columns ``t`` (s), ``x`` (m), ``F`` (friction force, N)
and ``normal`` (normal load, N); by default ``../shared/data/tribometer.csv`` relative to
the repository root (a public reciprocating-tribometer record: strokes of about 0.23 mm at
0.2-0.26 mm/s with dwells of about 1 s at each end, under 5 N). The file is read where it
is, never copied; the time column is used as given (the sampling is irregular).

**Preparation** (`prepare`):

1. *Sign.* The models' convention is that friction has the sign of the velocity. The
   correlation of ``sign(v)`` (backward difference, moving samples) with ``F`` is computed;
   if it is negative, ``F`` is flipped (``F_model = -F_file``) and the output says so.
2. *Normal load.* Only the samples from the first to the last one within `normal_tol`
   (1 %) of the load plateau (the median of the loaded part) are kept: the ramp-up at the
   start and the unloading at the end are dropped.
3. *Split in time.* The first `fit_fraction` (70 %) of the kept record's duration is
   fitted; the rest is held out for validation.

**Fits** (`fit_models`). The two-state model, GMS with 5 and 10 elements, LuGre and
Tustin, each with `fitting.fit` (Levenberg-Marquardt) from a start scaled to the data
(`scales`, `start_models`). The presliding fits are multimodal (GMS most of all: from the
estimated ``l1``, GMS-10 can end 25 % above what it reaches from half or twice that), so
the models whose start depends on ``l1`` (two-state, GMS) are fitted from ``l1`` times
each of `L1_FACTORS` and the fit with the lowest (weighted) sum of squares on the fit
samples, the cost the solver minimises, is kept. Only the parameters
these data determine are fitted (`FREE`); the others are held, for reasons found by
fitting them:

- every stroke runs at nearly one speed after an abrupt start, so the Stribeck velocity and
  exponent (``Vs``, ``delta``) cannot be told apart from ``Fc``: held (``Vs`` = a quarter of
  the median speed, ``delta = 1``). Fitted, ``sigma2`` ends at a few mN of force at most
  (two-state: zero); all it can explain is the +-8 % velocity noise of 0.1 um position
  steps: held at 0;
- the friction-lag parameter ``C`` (two-state, GMS) only acts when ``s(v)`` changes during
  motion, which it does not here (the 10x changes tried move the RMSE by 0.2 mN): held at
  the paper's time constant ``Fs/C``;
- ``Fs`` is fitted for the two-state model only: there it sets the rest value at a
  reversal (the force at which the new branch starts); in GMS, LuGre and Tustin it has no
  effect at this single speed;
- the two-state shape is fitted in `fitting.NormalizedPaperShape` coordinates ``l1``,
  ``alpha``, ``curvature``, with ``beta_rel`` and ``quartic`` held at the paper's values:
  freeing them as well lowers the fit RMSE by 0.4 % and not the validation RMSE, while
  ``l1``, ``curvature`` and ``quartic`` become correlated at +-1 (standard errors of 100 %);
- LuGre's ``sigma1``, fitted, goes to zero (it adds a force step ``sigma1*v`` at reversals
  that the data do not show) and the solver then creeps along its log scale until the step
  limit: held at 0.

*Dwell compression (exact).* The stage stands still for about half of the samples. Every
model's force is constant over a run of samples at one position (nothing moves, nothing
decays: docs/algorithm.md), so each such run of more than two samples is replaced by its
first and last samples, carrying the run's mean measured force and half its length as
weight. The simulation at the kept samples is identical to the full-rate one (the
backward-difference velocity of every moving sample is unchanged) and the weighted sum of
squares differs from the full-rate one by a constant: same optimum, same ``J^T J``, about
half the samples. Standard errors are rescaled to the full-rate sample count and residual
sum of squares (`ModelFit.stderr`). They assume independent residuals; these residuals are
dominated by systematic model error and are strongly correlated in time, so the standard
errors are lower bounds.

*Quick mode* (``--quick``, for tests and a first look) also keeps only every
`QUICK_STRIDE`-th moving sample (weight `QUICK_STRIDE`; the samples at which the motion
stops and starts are always kept). That is no longer exact, since the backward-difference
velocity then spans several samples, but the fit still sees the whole fit part, and the
metrics are computed as in a full run.

**Metrics.** Every fitted model is simulated once over the whole kept record at full rate,
from its zero state at the first kept sample, so the validation part is predicted with the
state the fit part left (a free-run prediction, not a refit). RMSE (N) and NRMSE (RMSE over
the range of the measured force in that part) are reported for the fitted samples and the
validation part.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from tribometer_data import (  # noqa: F401  (load, thin: the example's API, re-exported)
    load,
    prepare,
    Record,
    REGIMES,
    regimes,
    reversal_travel,
    strokes,
    thin,
)
from tribometer_plots import plot

import jaxfric
from fitting import _params, Dataset, fit, FitResult, NormalizedPaperShape
from fitting._staged import _estimate_l1
from jaxfric import paper
from jaxfric._fields import parameter_info
from jaxfric.motion import velocity


#: Default data file: ``../shared/data/tribometer.csv`` relative to the repository root.
DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "tribometer.csv"

#: Compared models, in table order.
MODELS = ("two_state", "gms5", "gms10", "lugre", "tustin")
#: Models whose start depends on the estimated ``l1``, and the multiples of it they are
#: fitted from (the best fit on the fit samples is kept; module docstring).
L1_MODELS = ("two_state", "gms5", "gms10")
L1_FACTORS = (1.0, 0.5, 2.0)

#: Fitted parameters per model (module docstring, "Fits"); the rest are held at their
#: starting values. GMS ``nu`` has n - 1 free coordinates (the weights sum to one).
FREE = {
    "two_state": ("Fs", "Fc", "l1", "alpha", "curvature"),
    "gms5": ("Fc", "nu", "k"),
    "gms10": ("Fc", "nu", "k"),
    "lugre": ("Fc", "sigma0"),
    "tustin": ("Fc",),
}

#: Quick mode keeps every `QUICK_STRIDE`-th moving sample for the fit (`thin`).
QUICK_STRIDE = 3

_SHAPE_NAMES = ("l1", "alpha", "beta_rel", "curvature", "quartic")


def units(f: ModelFit) -> dict[str, str]:
    """SI unit of every reported parameter of a fit (the paper's names and, for the
    two-state model, the `NormalizedPaperShape` coordinates), as declared on the fields."""
    shape = {i.name: i.unit for i in parameter_info(NormalizedPaperShape(1.0, 0.5, 0.1, 0.0, 0.0))}
    return {**shape, **_params.natural_units(f.result.model)}


# ---- starting models --------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Scales:
    """Scales read off a measurement to start the fits (SI).

    - `Fs`, `Fc` (N): 99th and 75th percentiles of ``|F|`` on moving samples (the peak and
      the sliding level; `Fc` at most 0.95 `Fs`).
    - `speed` (m/s): median ``|v|`` on moving samples; `Vs` (m/s): a quarter of it.
    - `l1` (m/N): from the travel after reversals over which the force rises by 90 % of
      ``2*Fs``, for the paper's shape (as `fitting.fit_staged` does).
    - `travel` (m): `reversal_travel`, where 90 % of the force reversal is done.
    - `C` (N/s): the paper's friction-lag time constant ``Fs/C`` (2.4 s) kept.
    """

    Fs: float
    Fc: float
    speed: float
    Vs: float
    l1: float
    travel: float
    C: float


def scales(t, x, F) -> Scales:
    """`Scales` of the measurement ``(t, x, F)`` (s, m, N; F with the sign of v)."""
    t, x, F = (np.asarray(a, dtype=np.float64) for a in (t, x, F))
    v = velocity(t, x)
    moving = v != 0
    if moving.sum() < 10:
        raise ValueError("the record hardly moves: cannot scale a starting model")
    fs = float(np.quantile(np.abs(F[moving]), 0.99))
    fc = min(float(np.quantile(np.abs(F[moving]), 0.75)), 0.95 * fs)
    speed = float(np.median(np.abs(v[moving])))
    base = NormalizedPaperShape.from_paper(paper.shape(), paper.stribeck().Fs)
    probe = jaxfric.TwoState(stribeck=jaxfric.Stribeck(Fs=fs, Fc=fc, Vs=speed / 4, delta=1.0),
                             shape=base, sigma2=0.0, C=1.0)
    l1 = _estimate_l1(probe, Dataset(t=t, x=x, F=F))
    if l1 is None or not np.isfinite(l1) or l1 <= 0:
        # No branch reached 90 % of the reversal: a quarter of the full travel.
        l1 = 0.25 * float(np.ptp(x)) / (2.0 * fs)
    travel = reversal_travel(x, F)
    if not np.isfinite(travel) or travel <= 0:
        travel = 2.0 * fs * float(l1)
    C = paper.C * fs / float(paper.stribeck().Fs)
    return Scales(Fs=fs, Fc=fc, speed=speed, Vs=speed / 4, l1=float(l1), travel=travel,
                  C=float(C))


def start_models(sc: Scales) -> dict[str, jaxfric.AbstractFrictionModel]:
    """Starting models scaled by `sc`, keyed as `MODELS`.

    Every model: ``Stribeck(Fs, Fc, Vs, delta=1)`` and ``sigma2 = 0``. Two-state: the
    paper's presliding shape (Sec. 6.2) rescaled to ``l1`` (self-similar in
    `NormalizedPaperShape` coordinates) and ``C`` from `sc`. GMS-n:
    `jaxfric.GMS.from_shape` of that shape with the breakpoints spread evenly,
    ``l1*(1, (n-1)/n, ..., 1/n)``: the measured reversal is nearly straight, and with the
    default geometric spacing (down to ``1e-3*l1``, right for the paper's steep shape) the
    fit switches the stiff elements off (weights -> 0: GMS-5 ends with 2 active elements,
    GMS-10 with 3) and then converges slowly or not at all. LuGre:
    ``sigma0 = ln(10)*Fc/travel`` (its bristle force then covers 90 % of a reversal within
    the measured `travel`), ``sigma1 = 0``.
    """
    stribeck = jaxfric.Stribeck(Fs=sc.Fs, Fc=sc.Fc, Vs=sc.Vs, delta=1.0)
    base = NormalizedPaperShape.from_paper(paper.shape(), paper.stribeck().Fs)
    shape = eqx.tree_at(lambda s: s.l1, base, jnp.asarray(sc.l1)).to_paper(sc.Fs)

    def gms(n):
        breakpoints = sc.l1 * jnp.asarray(np.linspace(1.0, 1.0 / n, n))
        return jaxfric.GMS.from_shape(shape, stribeck, 0.0, sc.C, n, breakpoints=breakpoints)

    return {
        "two_state": jaxfric.TwoState(stribeck=stribeck, shape=shape, sigma2=0.0, C=sc.C),
        "gms5": gms(5),
        "gms10": gms(10),
        "lugre": jaxfric.LuGre(stribeck=stribeck, sigma0=np.log(10.0) * sc.Fc / sc.travel,
                               sigma1=0.0, sigma2=0.0),
        "tustin": jaxfric.Tustin(stribeck=stribeck, sigma2=0.0),
    }


def count_free(model, free) -> int:
    """Number of fitted scalar coordinates of `model` for the names `free` (GMS weights
    count one fewer than elements: they sum to one)."""
    fit_model = _params.to_fit_representation(model)
    layout = _params.make_layout(fit_model, _params.default_props(fit_model, free))
    return int(sum(s for s, f in zip(layout.sizes, np.asarray(layout.leaf_free)) if f))


# ---- fitting ----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ModelFit:
    """One fitted model on the record.

    - `name`; `result`: the `fitting.FitResult` (its own metrics are on the compressed fit
      samples); `n_params`: fitted scalar coordinates; `seconds`: wall time of the fit,
      compilation included.
    - `force` (N): the fitted model simulated over the whole kept record at full rate.
    - `rmse_fit` (N), `nrmse_fit`: on the fit part at full rate; `rmse_val` (N),
      `nrmse_val`: on the validation part (NaN without one). NRMSE = RMSE / (max F - min F)
      of that part.
    - `stderr`: ``{name: standard error}`` in SI like `FitResult.stderr`, rescaled to the
      full-rate samples (module docstring); 0 for held parameters.
    - `shape_params`, `shape_stderr`: two-state only, the presliding shape in
      `NormalizedPaperShape` coordinates and their standard errors (same rescaling).
    - `overflow`: two-state memory-stack overflows over the record (0 expected).
    - `l1_factor`: the start (``l1`` times this factor, `L1_FACTORS`) whose fit was kept;
      `seconds` covers all the starts tried.
    - `rmse_val_by_regime`: validation RMSE (N) over the samples of each of `REGIMES`, with
      `presliding_travel` (m, the data's reversal travel from `scales`) as the border
      between presliding and sliding.
    """

    name: str
    result: FitResult
    n_params: int
    seconds: float
    force: np.ndarray
    rmse_fit: float
    nrmse_fit: float
    rmse_val: float
    nrmse_val: float
    stderr: dict[str, float]
    shape_params: dict[str, float]
    shape_stderr: dict[str, float]
    overflow: int
    rmse_val_by_regime: dict[str, float]
    presliding_travel: float
    l1_factor: float = 1.0

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)

    @property
    def params(self) -> dict[str, float]:
        """All parameter values (fitted and held), SI, in the paper's order."""
        return {k: float(self.result.params[k]) for k in self.result.names}


def _metrics(force: np.ndarray, F: np.ndarray) -> tuple[float, float]:
    if F.shape[0] == 0:
        return float("nan"), float("nan")
    rmse = float(np.sqrt(np.mean((force - F) ** 2)))
    return rmse, rmse / float(np.ptp(F))


def fit_models(record: Record, *, models=MODELS, quick: bool = False, max_steps: int = 256,
               log=print) -> dict[str, ModelFit]:
    """Fit each of `models` (names from `MODELS`) to the fit part of a prepared `record`.

    `quick` thins the moving samples by `QUICK_STRIDE` (`thin`); `max_steps` is the solver's
    iteration limit; `log` receives one progress line per model.

    **Returns:** ``{name: ModelFit}`` in the order of `models`.
    """
    unknown = [m for m in models if m not in MODELS]
    if unknown:
        raise ValueError(f"unknown model(s) {unknown}; choose from {', '.join(MODELS)}")
    t, x, F = record.t, record.x, record.F
    n_fit = record.split
    index, f_kept, weights = thin(t[:n_fit], x[:n_fit], F[:n_fit],
                                  QUICK_STRIDE if quick else 1)
    sc = scales(t[:n_fit], x[:n_fit], F[:n_fit])
    starts = start_models(sc)
    val = slice(record.split, t.size)
    masks = regimes(x, sc.travel)
    out = {}
    for name in models:
        start = time.perf_counter()
        factors = L1_FACTORS if name in L1_MODELS else (1.0,)
        tried = []
        for factor in factors:
            model0 = start_models(dataclasses.replace(sc, l1=sc.l1 * factor))[name]
            res = fit(model0, t[index], x[index], f_kept, free=FREE[name], weights=weights,
                      max_steps=max_steps)
            # Ranked by the weighted sum of squares the fit minimises (the full-rate one
            # when thinned: `thin`), not by the plain RMSE of the thinned samples, which
            # can favour a fit the solver itself rates worse.
            cost = float(np.sum(np.asarray(weights) * np.asarray(res.residuals) ** 2))
            tried.append((cost, factor, res))
        _, l1_factor, res = min(tried, key=lambda item: item[0])
        seconds = time.perf_counter() - start
        sim = jaxfric.simulate(res.model, t, x, full_output=True)
        force = np.asarray(sim.force)
        rmse_fit, nrmse_fit = _metrics(force[:n_fit], F[:n_fit])
        rmse_val, nrmse_val = _metrics(force[val], F[val])
        by_regime = {k: _metrics(force[val][m[val]], F[val][m[val]])[0]
                     for k, m in masks.items()}
        # cov = s^2 (J^T W J)^-1: the thinned J^T W J is the full-rate J^T J (exactly,
        # without quick thinning), so only s^2 = RSS/(N - p) needs the full-rate RSS and
        # sample count instead of the thinned ones that `fit` used.
        p = count_free(starts[name], FREE[name])
        rss_w = float(np.sum(weights * np.asarray(res.residuals) ** 2))
        rss = float(np.sum((force[:n_fit] - F[:n_fit]) ** 2))
        factor = float(np.sqrt((rss / max(n_fit - p, 1)) / (rss_w / max(index.size - p, 1))))
        shape_params, shape_stderr = {}, {}
        if isinstance(res.model, jaxfric.TwoState):
            natural = _params.natural_params(_params.to_fit_representation(res.model))
            sd = np.sqrt(np.diagonal(np.asarray(res.cov_fit)))
            for i, k in enumerate(res.fit_names):
                if k in _SHAPE_NAMES:
                    shape_params[k] = float(natural[k])
                    shape_stderr[k] = float(sd[i]) * factor
        out[name] = ModelFit(
            name=name, result=res, n_params=p, seconds=seconds, force=force,
            rmse_fit=rmse_fit, nrmse_fit=nrmse_fit, rmse_val=rmse_val, nrmse_val=nrmse_val,
            stderr={k: float(res.stderr[k]) * factor for k in res.names},
            shape_params=shape_params, shape_stderr=shape_stderr, overflow=int(sim.overflow),
            rmse_val_by_regime=by_regime, presliding_travel=sc.travel, l1_factor=l1_factor,
        )
        starts_note = (f" (best of {len(factors)} starts: l1 x {l1_factor:g})"
                       if len(factors) > 1 else "")
        log(f"  {name:>9s}: {res.status} after {int(res.num_steps)} steps{starts_note}, "
            f"{seconds:.1f} s; "
            f"RMSE fit {rmse_fit:.4f} N, validation {rmse_val:.4f} N")
    return out


@dataclasses.dataclass(frozen=True)
class Report:
    """What `run` produced: the prepared `record`, the `fits`, the number of samples given
    to the solver `n_solver` (after `thin`), the settings, and the wall time `seconds`
    (load to last fit)."""

    record: Record
    fits: dict[str, ModelFit]
    n_solver: int
    quick: bool
    fit_fraction: float
    seconds: float


def run(path: str | Path = DEFAULT_DATA, *, quick: bool = False, fit_fraction: float = 0.7,
        models=MODELS, log=print) -> Report:
    """Load, prepare and fit (module docstring); `log` receives progress lines."""
    start = time.perf_counter()
    record = prepare(load(path), fit_fraction=fit_fraction)
    n = record.split
    n_solver = thin(record.t[:n], record.x[:n], record.F[:n],
                    QUICK_STRIDE if quick else 1)[0].size
    log(describe(record, n_solver))
    fits = fit_models(record, models=models, quick=quick, log=log)
    return Report(record=record, fits=fits, n_solver=n_solver, quick=quick,
                  fit_fraction=fit_fraction, seconds=time.perf_counter() - start)


# ---- text and JSON ----------------------------------------------------------------------


def describe(record: Record, n_solver: int | None = None) -> str:
    """A few lines on the data and on what the preparation did to them; `n_solver` is the
    number of samples given to the solver."""
    t = record.t
    sign = "F flipped: F_model = -F_file" if record.sign_flipped else "F used as in the file"
    speed = np.abs(velocity(t, record.x))
    val = (f"validation: t >= {t[record.split]:.3f} s ({t.size - record.split} samples)"
           if record.split < t.size else "no validation part")
    return "\n".join([
        f"data: {record.source}",
        f"  {record.rows} rows; kept rows {record.kept[0]}..{record.kept[1] - 1} "
        f"(t = {t[0]:.3f}..{t[-1]:.3f} s): normal load within {100 * record.normal_tol:g} % "
        f"of its plateau {record.normal_plateau:.4g} N (kept: {record.normal.min():.4g} to "
        f"{record.normal.max():.4g} N)",
        f"  sign: corr(sign v, F_file) = {record.sign_correlation:+.3f} -> {sign}",
        f"  travel {1e3 * np.ptp(record.x):.4g} mm, speed up to {1e3 * speed.max():.3g} mm/s, "
        f"F from {record.F.min():.3f} to {record.F.max():.3f} N",
        f"  fit part: t < {t[record.split - 1]:.3f} s ({record.split} samples"
        + (f", {n_solver} given to the solver" if n_solver is not None else "") + f"); {val}",
    ])


def format_table(report: Report) -> str:
    """Markdown table: model, fitted parameters, RMSE/NRMSE on the fitted samples and on
    the validation part, convergence, solver steps and fit time."""
    lines = ["| model | fitted params | RMSE fit [N] | NRMSE fit | RMSE val [N] | NRMSE val | "
             "converged | steps | fit time [s] |",
             "|---|---:|---:|---:|---:|---:|---|---:|---:|"]
    for name, f in report.fits.items():
        status = "yes" if f.converged else f"no ({f.result.status})"
        lines.append(f"| {name} | {f.n_params} | {f.rmse_fit:.4f} | {f.nrmse_fit:.4f} | "
                     f"{f.rmse_val:.4f} | {f.nrmse_val:.4f} | {status} | "
                     f"{int(f.result.num_steps)} | {f.seconds:.1f} |")
    return "\n".join(lines)


def format_regimes(report: Report) -> str:
    """Markdown table of the validation RMSE per regime (`regimes`), with the share of the
    validation samples in each."""
    fits = list(report.fits.values())
    if not fits:
        return ""
    r = report.record
    val = slice(r.split, r.t.size)
    masks = regimes(r.x, fits[0].presliding_travel)
    share = {k: float(np.mean(m[val])) if r.split < r.t.size else float("nan")
             for k, m in masks.items()}
    lines = ["| model | " + " | ".join(
        f"{k} [N] ({100 * share[k]:.0f} %)" for k in REGIMES) + " |",
        "|---|" + "---:|" * len(REGIMES)]
    for name, f in report.fits.items():
        lines.append(f"| {name} | " + " | ".join(
            f"{f.rmse_val_by_regime[k]:.4f}" for k in REGIMES) + " |")
    return "\n".join(lines)


def format_parameters(f: ModelFit) -> str:
    """Markdown table of a fit's parameters: value, standard error ("held" for parameters
    that were not fitted), SI unit.

    For the two-state model, the paper's symbols are followed by the shape in the fitted
    `NormalizedPaperShape` coordinates and two derived scales: the presliding travel
    ``2*Fs*l1`` (m) and the friction-lag time scale ``Fs/C`` (s).
    """
    lines = ["| parameter | value | std. error | unit |", "|---|---:|---:|---|"]
    rows = [(k, k, v, f.stderr[k]) for k, v in f.params.items()]
    rows += [(f"{k} (normalised shape)", k, f.shape_params[k], f.shape_stderr[k])
             for k in f.shape_params if k not in ("l1", "alpha")]
    unit = units(f)
    for label, k, v, s in rows:
        # Held parameters have exactly zero rows in the covariance.
        lines.append(f"| {label} | {v:.6g} | {f'{s:.3g}' if s > 0 else 'held'} | {unit[k]} |")
    if isinstance(f.result.model, jaxfric.TwoState):
        m = f.result.model
        fs = float(m.stribeck.Fs)
        lines.append(f"| 2*Fs*l1 (presliding travel) | {2 * fs * float(m.shape.l1):.4g} | | m |")
        lines.append(f"| Fs/C (friction-lag time scale) | {fs / float(m.C):.4g} | | s |")
    return "\n".join(lines)


def _num(v) -> float | None:
    v = float(v)
    return v if np.isfinite(v) else None


def to_json(report: Report) -> dict:
    """The report as JSON-ready data (NaN and inf become null)::

        {"data": {...}, "sign_flipped": bool, "quick": bool, "seconds": s,
         "models": {name: {"rmse_fit", "nrmse_fit", "rmse_val", "nrmse_val", "converged",
                           "status", "num_steps", "n_params", "free", "params", "stderr",
                           "units", ...}}}
    """
    r = report.record
    models = {}
    for name, f in report.fits.items():
        entry = {
            "n_params": f.n_params,
            "free": list(f.result.free),
            "rmse_fit": _num(f.rmse_fit),
            "nrmse_fit": _num(f.nrmse_fit),
            "rmse_val": _num(f.rmse_val),
            "nrmse_val": _num(f.nrmse_val),
            "rmse_val_by_regime": {k: _num(v) for k, v in f.rmse_val_by_regime.items()},
            "converged": f.converged,
            "status": f.result.status,
            "num_steps": int(f.result.num_steps),
            "fit_seconds": f.seconds,
            "l1_start_factor": f.l1_factor,
            "overflow": f.overflow,
            "params": {k: _num(v) for k, v in f.params.items()},
            "stderr": {k: _num(v) for k, v in f.stderr.items()},
            "units": {k: units(f)[k] for k in f.params},
        }
        if f.shape_params:
            entry["shape_normalized"] = {k: _num(v) for k, v in f.shape_params.items()}
            entry["shape_normalized_stderr"] = {k: _num(v) for k, v in f.shape_stderr.items()}
        models[name] = entry
    t = r.t
    return {
        "data": {
            "source": r.source,
            "rows": r.rows,
            "kept_rows": [r.kept[0], r.kept[1]],
            "t_start_s": float(t[0]),
            "t_end_s": float(t[-1]),
            "t_split_s": float(t[r.split]) if r.split < t.size else None,
            "fit_fraction": report.fit_fraction,
            "n_fit": r.split,
            "n_solver": report.n_solver,
            "n_val": int(t.size - r.split),
            "normal_plateau_N": r.normal_plateau,
            "normal_tol": r.normal_tol,
            "normal_min_N": float(r.normal.min()),
            "normal_max_N": float(r.normal.max()),
            "sign_correlation_file": _num(r.sign_correlation),
            "force_convention": "F_model = -F_file" if r.sign_flipped else "F_model = F_file",
            "presliding_travel_m": next(
                (f.presliding_travel for f in report.fits.values()), None),
        },
        "sign_flipped": r.sign_flipped,
        "quick": report.quick,
        "seconds": report.seconds,
        "models": models,
    }


# ---- command line -----------------------------------------------------------------------


def main(argv=None) -> int:
    """``python examples/tribometer.py``: see the module docstring and ``--help``."""
    ap = argparse.ArgumentParser(
        prog="examples/tribometer.py",
        description="Fit the two-state model, GMS-5, GMS-10, LuGre and Tustin to a real "
                    "tribometer record (t, x, F, normal in SI) and compare them on a "
                    "held-out part.",
    )
    ap.add_argument("--data", metavar="PATH", default=str(DEFAULT_DATA),
                    help="CSV with columns t [s], x [m], F [N], normal [N] "
                         "(default: %(default)s)")
    ap.add_argument("--json", metavar="OUT.json", help="write the results as JSON")
    ap.add_argument("--out", metavar="DIR", help="write PNG figures into DIR")
    ap.add_argument("--quick", action="store_true",
                    help=f"fit only one moving sample in {QUICK_STRIDE} (approximate, "
                         "somewhat faster; for tests)")
    ap.add_argument("--fit-fraction", type=float, default=0.7,
                    help="fraction of the record (in time) fitted; the rest validates "
                         "(default: %(default)s)")
    args = ap.parse_args(argv)
    if not Path(args.data).is_file():
        print(f"error: tribometer data not found at {args.data}\n"
              "  pass --data PATH (a CSV with columns t, x, F, normal in SI units)",
              file=sys.stderr)
        return 2
    try:
        report = run(args.data, quick=args.quick, fit_fraction=args.fit_fraction)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print()
    print(format_table(report))
    fits = list(report.fits.values())
    if fits:
        print(f"\nvalidation RMSE by regime (presliding: moving, less than "
              f"{1e3 * fits[0].presliding_travel:.3g} mm from the last reversal; share of "
              "the validation samples in brackets)")
        print(format_regimes(report))
    if "two_state" in report.fits:
        print("\ntwo-state model (standard errors assume independent residuals: lower "
              "bounds here)")
        print(format_parameters(report.fits["two_state"]))
    print(f"\ntotal {report.seconds:.1f} s" + (" (quick)" if report.quick else ""))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(to_json(report), indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.out:
        for path in plot(report, args.out):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
