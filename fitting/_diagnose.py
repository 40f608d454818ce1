"""`diagnose`: fit a model, then add the missing physical effects that full refits and
blocked cross-validation support, with one rule (the decision is `fitting._select`, its
thresholds `fitting.DiagnosisRules`; docs/diagnosis.md explains it).

Several runs (a list of `fitting.Dataset`) are one `fitting._candidates.Data`, the runs
concatenated; every fit fits them all at once (`fitting._refits.Fitter.fit`), and the
folds are the runs (`fitting._select.run_folds`, leave one run out).

What is searched (`effect_names`): every effect of `jaxfric.effects` with a linear
parameter not already in the model (those of an angle only on rotary data, those of a load
only with a load signal), and other base models (`default_base_models`: a GMS with 20
elements started at the fitted two-state model's presliding curve and one read off the
data; a LuGre read off the data).

A long record (at least twice `search_samples` samples) is searched on a copy
(`_search_copy`): about `search_samples` samples evenly in time (one in k), as many again
evenly in the change of the base model's states (its parts: hysteresis, lag, elements),
and every start, stop and reversal with the sample before it: the base model, fitted on every
sample first (that fit is the baseline reported), is simulated on every sample, and the
copy keeps what its states need: the exact reversal points, and dense samples where its
presliding and lag change fast (after reversals and starts, through a steep Stribeck
curve), which a copy of one sample in k smears over its long steps. The copy is faithful
when the base model and the base models the search tries instead (started from its
fit) simulated on it are within the force's noise of their full-rate simulations; its
size is doubled until it is. It keeps the full-rate velocity and acceleration estimates
at its samples, so an effect's relation to them is kept; the force is not averaged, which
would smear short accelerations. Its time column is uneven: the held-out blocks are of
equal duration (`fitting._select.time_block_folds`), and the search's errors (training
and held out) weigh the stretches where the states change fast more than the record does.
The final model is then refitted on every sample from where the search left it, and the
errors of the fits on every sample are reported (the held-out errors are the search's
cross-validation).
"""

from collections.abc import Callable, Sequence

import numpy as np

import jaxfric
from jaxfric import effects as fx
from jaxfric.motion import consistent_velocity

from ._base_options import base_model_starts, default_base_models
from ._blas import single_threaded_blas
from ._candidates import _code, Candidate, Data
from ._data import check_dataset, Dataset
from ._derivatives import describe, estimate_acceleration, estimate_derivatives
from ._diagnosis import Diagnosis, Step
from ._folds import _blocks, run_folds, time_block_folds
from ._params import leaf_names, to_fit_representation
from ._per_run import per_run_values, run_model
from ._plausibility import plausibility
from ._refits import Fitter, Option
from ._regimes import regime_errors, regimes
from ._rules import DiagnosisRules
from ._select import held_out_sse, select
from ._start import lag_starts


#: A record of at least twice this many samples is searched on about this many.
SEARCH_SAMPLES = 5_000


def _contained(model, fixed) -> set[str]:
    """Effects the model's own free parameters already are: ``viscous`` (``c_visc * v``)
    when the model fits its own ``sigma2``: their sum is one viscous coefficient, so adding
    it enlarges nothing. Searched by default only when ``sigma2`` is held with `fixed`."""
    names = set(leaf_names(model)) - set(fixed)
    return {"viscous"} if "sigma2" in names else set()


def effect_names(effects, present, rotary: bool, has_load: bool = False) -> list[str]:
    """The effects a diagnosis searches: `effects` (default every effect, those of an angle,
    `jaxfric.effects.ROTARY_EFFECTS`, only if `rotary`, those of the load,
    `jaxfric.effects.LOAD_EFFECTS`, only if `has_load`) not in `present`. A load effect
    asked for without a load signal raises `ValueError`."""
    default = [n for n in fx.EFFECTS if (rotary or n not in fx.ROTARY_EFFECTS)
               and (has_load or n not in fx.LOAD_EFFECTS)]
    if effects and not has_load and set(effects) & set(fx.LOAD_EFFECTS):
        raise ValueError(f"effect(s) {sorted(set(effects) & set(fx.LOAD_EFFECTS))} need the "
                         "load signal (a 'load' column, or diagnose(..., load=...))")
    return [n for n in (effects or default) if n not in present]


def _checked(name, arr, t):
    if arr is None:
        return None
    arr = np.asarray(arr, np.float64)
    if arr.shape != t.shape:
        raise ValueError(f"{name} has shape {arr.shape}, t has {t.shape}")
    return arr


def _record(t, x, F, v, a, load, derivatives, velocity_window) -> tuple[Data, str]:
    """The checked record (`Data`, SI) with its velocity and acceleration estimates, and
    how they were obtained (`fitting._derivatives.describe`)."""
    t, x, F = (np.asarray(arr, np.float64) for arr in (t, x, F))
    how = describe(derivatives, velocity_window, column=v is not None,
                   acceleration_column=a is not None)
    if v is None:
        v, a_est = estimate_derivatives(t, x, derivatives, velocity_window)
    else:
        v = _checked("v", v, t)
        a_est = estimate_acceleration(t, v, derivatives, velocity_window)
    a = a_est if a is None else _checked("a", a, t)
    load = _checked("load", load, t)
    check_dataset(Dataset(t=t, x=x, F=F, v=v, load=load, a=a))  # one clear error, early
    return Data(t, x, np.asarray(v, np.float64), F, a, load), how


def noise_level(F) -> float:
    """A robust estimate of the force's white noise (N): the median absolute deviation of
    its sample-to-sample changes over sqrt(2) (steps and reversals are rare outliers)."""
    d = np.diff(np.asarray(F, float))
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def _reversals(d: Data) -> np.ndarray:
    """The samples (indices into `d`) at which a memory model's direction of motion
    (-1, 0 or 1) changes: every reversal, start and stop, each with the sample before it
    (a reversal's point, ``x_prev``). The direction is `jaxfric.motion.Motion`'s: the sign
    of the velocity made consistent with the position step
    (`jaxfric.motion.consistent_velocity`)."""
    out = []
    for sl, r in zip(d.slices(), d.runs()):
        v = consistent_velocity(r.v, np.diff(r.x, prepend=r.x[:1]),
                                np.diff(r.t, prepend=r.t[:1]))
        d = np.sign(np.asarray(v))
        turn = np.flatnonzero(d[1:] != d[:-1]) + 1
        out.append(sl.start + np.concatenate([turn - 1, turn]))
    return np.concatenate(out)


def _full_rate(full: Data, model) -> tuple[np.ndarray, np.ndarray]:
    """`model`'s force on every sample of `full` (N, runs concatenated) and how fast its
    states change: per sample, the sum over its parts (`jaxfric.SimResult.parts`: the
    hysteresis, the lag, each element, ...; not the stack depth) of their change from the
    sample before (N; 0 at each run's first sample). The parts, not their sum: a fast lag
    cancels most of a steep change of the Stribeck curve in the force, not in the states
    a long step integrates."""
    force, change = [], []
    for i, r in enumerate(full.runs()):
        res = jaxfric.simulate(run_model(model, i), r.t, r.x, r.v, load=r.load, a=r.a,
                               full_output=True)
        parts = [np.asarray(p, float) for k, p in res.parts.items()
                 if k not in ("depth", "base") and np.shape(p) == r.t.shape]
        force.append(np.asarray(res.force, float))
        change.append(np.r_[0.0, sum(np.abs(np.diff(p)) for p in parts or [force[-1]])])
    return np.concatenate(force), np.concatenate(change)


def _spread(d: Data, change: np.ndarray, m: int) -> np.ndarray:
    """About `m` samples of each run evenly in time (one in ``k = n / m``), and as many
    again evenly in W, the cumulated change of the base model's states (`change` per
    sample, `_full_rate`), each run's share in proportion to its length (indices into
    `d`): ``2 m`` samples evenly spaced in ``u = (t - t_0) / T + W / W_total``. So every
    stretch is sampled at least as densely as one in k, and where the states change
    fast, densely; the first and last sample of each run are kept."""
    out = []
    for sl in d.slices():
        t = d.t[sl]
        w = np.cumsum(np.r_[0.0, change[sl][1:]])
        u = (t - t[0]) / max(t[-1] - t[0], 1e-300) + (w / w[-1] if w[-1] > 0 else 0.0)
        mi = max(2, round(2 * m * t.size / d.t.size))
        pick = np.searchsorted(u, np.linspace(0.0, u[-1], mi))
        out.append(sl.start + np.r_[np.minimum(pick, t.size - 1), t.size - 1])
    return np.concatenate(out)


def _search_copy(full: Data, model, m: int, log, others=()) -> tuple[Data, np.ndarray, str]:
    """The samples a diagnosis searches on, their indices into `full`, and what was
    measured, in words: about `m` (`_spread`, by the state changes of every model) and
    every reversal with the sample before it (`_reversals`), `m` doubled until the copy is
    faithful: `model` (the base model fitted on every sample: the model the search starts
    from and compares against) and each of `others` (``[(name, model)]``: the base models
    the search tries instead, started from that fit) simulated on the copy are within the
    force's noise (`noise_level`), RMS, of their simulations on every sample. A state
    model integrates its presliding and lag over each step of its time column (`t` may be
    uneven), so a copy is another discretisation. A copy one sample in k misses the
    reversal points (the memory's branch starts) and charges the lag's forcing over a long
    step after each reversal and start at the end of the step, where the presliding
    factor of that forcing has grown: an error that outlasts the step by the lag's time
    constant. Both are kept here. Every sample when no copy of at most half of them is
    faithful."""
    sigma = noise_level(full.F)
    models = [("the base model", model), *others]
    sims = [_full_rate(full, mod) for _, mod in models]
    change = sum(c for _, c in sims)
    turns = _reversals(full)
    words = ""
    while 2 * m <= full.t.size:
        copy, idx = full.take(np.r_[_spread(full, change, m), turns])
        if 2 * idx.size > full.t.size:
            break
        errs = [float(np.sqrt(np.mean((copy.simulate(mod) - ref[idx]) ** 2)))
                for (_, mod), (ref, _) in zip(models, sims)]
        worst = int(np.argmax(errs))
        err, name = errs[worst], models[worst][0]
        if err <= sigma:
            return copy, idx, (f"{words}{'its' if len(models) == 1 else 'their'} "
                               f"simulation{'s differ' if len(models) > 1 else ' differs'} "
                               f"from the full-rate one by at most {err:.2g} N RMS, within "
                               f"the force's noise, {sigma:.2g} N")
        words += f"{idx.size} samples would change {name}'s simulation by {err:.2g} N RMS; "
        log(f"{idx.size} samples would change {name}'s simulation by {err:.2g} N RMS, more "
            f"than the force's noise ({sigma:.2g} N): a denser copy")
        m *= 2
    copy, idx = full.take(np.arange(full.t.size))
    return copy, idx, (f"not subsampled: {words.rstrip('; ')}, more than the force's "
                       f"noise ({sigma:.2g} N)" if words else
                       "not subsampled: its reversals are more than half of its samples")


def _records(runs: Sequence[Dataset], derivatives, velocity_window) -> tuple[Data, str]:
    """Several runs (`Dataset`s; a known force subtracted from `F`) as one `Data`, runs
    concatenated in order, each with its own derivative estimates."""
    parts, hows = [], []
    for i, d in enumerate(runs):
        if d.weights is not None:
            raise ValueError(f"run {i}: diagnose uses every sample (weights not supported)")
        if (d.load is None) != (runs[0].load is None):
            raise ValueError(f"run {i}: every run needs a load signal, or none")
        F = np.asarray(d.F, np.float64) - (0.0 if d.known is None else np.asarray(d.known))
        try:
            one, how = _record(d.t, d.x, F, d.v, d.a, d.load, derivatives, velocity_window)
        except ValueError as e:
            raise ValueError(f"run {i}: {e}") from None
        parts.append(one)
        hows.append(how)
    if len(parts) == 1:
        return parts[0], hows[0]
    cat = [None if getattr(parts[0], f) is None else
           np.concatenate([getattr(p, f) for p in parts])
           for f in ("t", "x", "v", "F", "a", "load")]
    return Data(*cat, tuple(p.t.size for p in parts)), hows[0]


def _masks(data: Data) -> dict:
    """The regimes (`fitting.regimes`) of every sample; for several runs each run's, with
    the sliding speed bands common to all (the terciles of their sliding speeds)."""
    if data.n_runs == 1:
        return regimes(data.t, data.x, data.v)
    runs = data.runs()
    own = [regimes(r.t, r.x, r.v) for r in runs]
    speeds = []
    for r, o in zip(runs, own):
        slide = np.zeros(r.t.size, bool)
        for name, mask in o.items():
            if name.startswith("sliding"):
                slide |= mask
        speeds.append(np.abs(r.v[slide]))
    speeds = np.concatenate(speeds)
    bands = list(np.quantile(speeds, [1 / 3, 2 / 3])) if speeds.size else None
    own = [regimes(r.t, r.x, r.v, speed_bands=bands) for r in runs]
    names = list(dict.fromkeys(n for o in own for n in o))
    return {n: np.concatenate([o.get(n, np.zeros(r.t.size, bool)) for o, r in zip(own, runs)])
            for n in names}


def _prune(model, on):
    """The superset `model` with only the effects in `on` (indices), the base plain if none."""
    effects = getattr(model, "effects", ())
    base = model.without_effects() if effects else model
    kept = tuple(effects[i] for i in sorted(on))
    return base + kept if kept else base


def _final_fit(fitter: Fitter, model, on, copy: Data, full: Data, log, what: str):
    """The `FitResult` of `model` (pruned) refitted on every sample of `full` (or on `copy`
    when the search used every sample)."""
    pruned = _prune(model, on)
    if full.t.size != copy.t.size:
        log(f"refitting {what} on all {full.t.size} samples ...")
    f = Fitter(full, fitter.fixed, fitter.max_steps)
    f.fit(pruned, frozenset(range(len(getattr(pruned, "effects", ())))))
    return f.last


def _prediction(res) -> np.ndarray:
    """A `FitResult`'s prediction on every sample (runs concatenated)."""
    p = res.prediction
    return np.concatenate([np.asarray(q) for q in p]) if isinstance(p, tuple) else np.asarray(p)


def _step(res, added, full: Data, holdout_rmse: float, masks, start: str = "") -> Step:
    resid = _prediction(res) - full.F
    return Step(added=list(added), fit=res, start=start, rmse=float(np.sqrt(np.mean(resid**2))),
                rmse_holdout=holdout_rmse, regimes=regime_errors(-resid, masks),
                rel_error=float(np.sqrt(np.mean(resid**2) / np.mean(full.F**2))))


def _held_out(o: Option, folds, data: Data) -> list[float]:
    """The RMSE of `o`'s held-out predictions on each run of `data` (every sample is held
    out once; NaN when `o` was not cross-validated)."""
    if not o.fold_preds:
        return [float("nan")] * data.n_runs
    pred = np.full(data.t.size, np.nan)
    for k, idx in _blocks(folds):
        pred[idx] = o.fold_preds[k][idx]
    return [float(np.sqrt(np.nanmean((pred - data.F)[sl] ** 2))) for sl in data.slices()]


def _run_rows(names, full: Data, copy: Data, folds, options, fits) -> list[dict]:
    """Per run: its samples, the held-out RMSE of the baseline and after each addition
    (`rmse_holdout`), and the in-sample RMSE of the baseline and final fits (`rmse`)."""
    held = [_held_out(o, folds, copy) for o in options]
    ins = [[float(np.sqrt(np.mean((_prediction(r) - full.F)[sl] ** 2))) for sl in full.slices()]
           for r in fits]
    values = per_run_values(fits[-1].fit_model)
    return [{"run": name, "samples": int(sl.stop - sl.start),
             "rmse_holdout": [h[i] for h in held], "rmse": [r[i] for r in ins],
             **({"params": values[i]} if values else {})}
            for i, (name, sl) in enumerate(zip(names, full.slices()))]


def _or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _scores(o: Option) -> dict:
    """An option's training SSE and, where it was cross-validated, its held-out gain and
    z, for ``trials`` (a base-model option's other starts too)."""
    return {"sse_train": o.sse, "held_out_share_removed": _or_none(o.gain),
            "z": _or_none(o.z)}


def _candidate(o: Option, current: Option, added: bool) -> Candidate:
    new = sorted(o.on - current.on)
    effect = o.fitted.effects[new[0]] if new else None
    judged = np.isfinite(o.z)
    pair = len(o.names) > 1
    worth = o.sse < (o.against if np.isfinite(o.against) else current.sse) - o.optimism
    why = ((f"{o.start}; " if o.start else "")
           + f"refit removes {100 * (1 - o.sse / current.sse):.3g} % of the training SSE"
           + (f"; held out {100 * o.gain:.3g} % of the SSE (of a typical block at least "
              f"{100 * o.lower:.3g} %), z = {o.z:.2f}" if judged else
              "; not cross-validated (it cannot qualify)" if o.skipped else
              "; not cross-validated (not among the best training fits)" if worth else
              "; not cross-validated (its second effect removes no more than fitting noise "
              "removes, 2 q s^2, beyond its better single)" if pair else
              "; not cross-validated (no more than fitting noise removes, 2 q s^2)")
           + (f"; not physical: {o.physical}" if o.physical else "")
           + (f"; not converged: {o.unconverged}" if o.unconverged else "")
           + (f"; judged where its fold fits stopped at their step limit ({o.cut})"
              if o.cut else ""))
    if effect is not None:
        why = f"{effect.describe()}; {why}"
    return Candidate(name=o.name, effect=effect, score=float(o.gain if judged else np.nan),
                     t_stat=float(o.z), significant=added, evidence=why,
                     code=_code(effect) if effect is not None else f"base model {o.name}")


def _by_gain(options):
    """The cross-validated options by held-out gain (largest first), then the others by
    training error (as `select` sorted them)."""
    judged = sorted((o for o in options if np.isfinite(o.gain)), key=lambda o: -o.gain)
    return judged + [o for o in options if not np.isfinite(o.gain)]


@single_threaded_blas()  # for all of it: its fits run side by side (`fitting._blas`)
def diagnose(
    model, t, x=None, F=None, v=None, *,
    effects: Sequence[str] | None = None,
    rules: DiagnosisRules | None = None,
    folds=None,
    base_models: Sequence[tuple[str, object]] | None = None,
    max_steps: int = 150,
    max_added: int = 4,
    fixed: Sequence[str] = (),
    model_name: str | None = None,
    derivatives: str = "central",
    velocity_window: float | None = None,
    log: Callable[[str], None] | None = None,
    rotary: bool = False,
    load=None,
    search_samples: int | None = SEARCH_SAMPLES,
    a=None,
    run_names: Sequence[str] | None = None,
) -> Diagnosis:
    """Fit `model` to ``(t, x, F[, v])`` (SI), or to several runs (`t` a list of
    `fitting.Dataset`, as `fitting.fit_datasets` takes), and add, one round at a time, the
    missing effect that full refits and cross-validation support (`fitting._select`;
    docs/diagnosis.md).

    - Several runs: every fit fits all runs at once (each from its own zero state, shared
      physical parameters, a per-run parameter, ``param(..., per_run=True)``, per run);
      the folds are the runs (leave one run out, `fitting._select.run_folds`): an effect
      is added only when it lowers the error of runs it was not fitted on. A run's
      `known` force is subtracted; `x`, `F`, `v`, `a`, `load` are then not given (each
      `Dataset` has its own). `run_names` names the runs in the result (default 1, 2, ...).
    - `rules`: the thresholds (`DiagnosisRules`, every one documented there).
    - `folds`: ``[(train_weights, test_weights)]`` over the samples (runs concatenated;
      default: the runs, or for one run the time blocks of `rules`,
      `fitting._select.time_block_folds`); each contiguous stretch of a fold's held-out
      samples of one test weight is then a block of the rule.
    - `effects`: names from `jaxfric.effects.EFFECTS` to search (default `effect_names`:
      every effect not already in the model, nor one of its free parameters: ``viscous``
      only when ``sigma2`` is held with `fixed`; the effects of an angle only when
      `rotary`, `x` then an angle in rad; those of the load only with `load`).
    - `base_models`: ``[(name, start)]`` tried as replacements of the base model by the
      same rule; a start is a plain model or a function of the fitted plain model that
      returns one, or several starts ``((label, start), ...)``, each fitted, the best
      held-out one kept (`fitting._select._held_out_race`; default `default_base_models`:
      a GMS with 20 elements, started where the fit is and read off the data, and a LuGre
      read off the data; ``()`` for none); when one is added,
      ``Diagnosis.finding`` says that the base model is the limit here.
    - `fixed`: parameter names of `model` held at their values in every fit.
    - `max_steps`: per fit. `max_added`: at most this many rounds add something (an
      effect, a pair, or a base model): a budget, like `max_steps`, not a threshold of the
      rule. `load`: the transmitted load (N, or N m), for the load effects.
    - `derivatives`, `velocity_window`: how the velocity is estimated from the position
      when `v` is not given (``"central"``, ``"savgol"`` or ``"backward"``,
      `fitting._derivatives`), and the acceleration `jaxfric.effects.Inertia` reads by the
      same method, unless `a` (m/s^2) is given.
    - `search_samples`: a record of at least twice as many samples (all runs together) is
      searched on about this many (`_search_copy`: where faithful; each run in proportion
      to its length) and the final model refitted on all; None or 0 searches on every
      sample.
    - `log`: called with a line of progress for every fit.

    Returns a `Diagnosis`; its models are in the fit representation
    (`fitting.to_fit_representation`); with per-run parameters, ``Diagnosis.model`` has
    them at their mean over the runs (for a run not fitted) and
    ``fitting.run_model(d.final.fit.fit_model, i)`` is run ``i``'s model.
    """
    log = log or (lambda *_: None)
    rules = _rules(rules, max_added)
    full, how, given_v = _inputs(t, x, F, v, a, load, derivatives, velocity_window)
    names_of_runs = list(run_names) if run_names is not None else [
        str(i + 1) for i in range(full.n_runs)]
    if len(names_of_runs) != full.n_runs:
        raise ValueError(f"run_names: {len(names_of_runs)} names for {full.n_runs} runs")
    model = to_fit_representation(model)
    unknown = set(fixed) - set(leaf_names(model))
    if unknown:
        raise ValueError(f"fixed: {type(model).__name__} has no parameter(s) "
                         f"{sorted(unknown)}; it has {leaf_names(model)}")
    base_models = (default_base_models(model, full.longest(), fixed) if base_models is None else
                   [(name, starts if isinstance(starts, tuple) else (("as given", starts),))
                    for name, starts in base_models])
    if any(not starts for _, starts in base_models):
        raise ValueError("base_models: every base model needs a start")
    n = full.t.size
    base_full, search, won, copy, pick = None, "", "", full, np.arange(n)
    if search_samples and n >= 2 * search_samples:  # the baseline, the copy's judge
        log(f"fitting the base model on all {n} samples ...")
        f = Fitter(full, fixed, max_steps, log)
        won = f.race(starts := lag_starts(model, fixed),  # the winner starts the copy
                     frozenset(range(len(getattr(model, "effects", ())))))[2]
        model = dict(starts).get(won, model)
        base_full, fit = f.last, f.last.fit_model
        tried = base_model_starts(base_models, fit)
        copy, pick, faithful = _search_copy(full, fit, search_samples, log, tried)
        search = (f"effects searched on {copy.t.size} of the {n} samples (about "
                  f"{search_samples} evenly in time, as many where the base model's states "
                  f"change, every reversal kept; {faithful}); "
                  f"the baseline and final model refitted on all {n}"
                  if copy.t.size < n else faithful)
    if search:
        log(search)
    folds, by = _folds(folds, pick, copy, rules, log)
    present = {e.name for e in getattr(model, "effects", ())}
    names = effect_names(effects, present | _contained(model, tuple(fixed)) if not effects
                         else present, rotary, full.load is not None)
    fitter = Fitter(copy, fixed, max_steps, log)
    rounds = select(fitter, model, names, folds, rules,
                    base_options=lambda: list(base_models), log=log, race=base_full is None,
                    max_added=max_added)
    masks = _masks(full)
    n_copy = copy.t.size

    def cv_rmse(o):
        return float(np.sqrt(held_out_sse(o, folds, copy.F) / n_copy)) if o.fold_preds \
            else float("nan")

    first = rounds[0].current
    base_res = (base_full if base_full is not None else
                _final_fit(fitter, first.fitted, first.on, copy, full, log, "the baseline"))
    baseline = _step(base_res, [], full, cv_rmse(first), masks, won or first.start)
    steps, added, findings = [], [], []
    chosen = [r.added for r in rounds if r.added is not None]
    held = "runs" if by == "runs" else "blocks"
    for i, o in enumerate(chosen):
        added = [*added, *o.names]
        if o.base:
            findings.append(f"the base model is the limit here: {o.name} predicts the "
                            f"held-out {held} better ({100 * o.gain:.3g} % of their SSE, "
                            f"z = {o.z:.2f}) than any effect added to the base model")
        if o.ties:
            findings.append(f"{o.name} was added, but "
                            + " and ".join(f"{n} (difference z = {z:.2f})" for n, z in o.ties)
                            + (" predicts" if len(o.ties) == 1 else " predict")
                            + f" the held-out {held} about as well: the data do not "
                            "tell them apart")
        last = i == len(chosen) - 1
        res = (_final_fit(fitter, o.fitted, o.on, copy, full, log, " + ".join(added))
               if last else o.result)
        steps.append(_step(res, added, full if last else copy, cv_rmse(o),
                           masks if last else _masks(copy)))
    runs = _run_rows(names_of_runs, full, copy, folds, [first, *chosen],
                     [base_res, *([steps[-1].fit] if steps else [])])
    return _result(rounds, baseline, steps, base_res, full, search, "; ".join(findings), by,
                   runs,
                   model_name or type(model).__name__, how,
                   None if given_v else {"method": derivatives, "window_s": velocity_window},
                   log)


def _rules(rules: DiagnosisRules | None, max_added: int) -> DiagnosisRules:
    """`rules` (default `DiagnosisRules()`), the budget `max_added` checked with them."""
    if max_added < 0:
        raise ValueError(f"max_added must be >= 0, got {max_added}")
    return DiagnosisRules() if rules is None else rules


def _inputs(t, x, F, v, a, load, derivatives, velocity_window) -> tuple[Data, str, bool]:
    """The record (`Data`) of one run ``(t, x, F, ...)`` or of several (`t` a list of
    `Dataset`), how the velocity was obtained, and whether it was given."""
    if isinstance(t, list | tuple) and t and all(isinstance(d, Dataset) for d in t):
        if any(arr is not None for arr in (x, F, v, a, load)):
            raise ValueError("diagnose(model, [Dataset, ...]): x, F, v, a and load are "
                             "given per run, in each Dataset")
        full, how = _records(list(t), derivatives, velocity_window)
        return full, how, all(d.v is not None for d in t)
    if x is None or F is None:
        raise ValueError("diagnose needs t, x and F (or a list of fitting.Dataset)")
    full, how = _record(t, x, F, v, a, load, derivatives, velocity_window)
    return full, how, v is not None


def _folds(folds, pick, copy: Data, rules: DiagnosisRules, log) -> tuple[list, str]:
    """The folds on the searched samples, and what they are: ``"given"``, ``"runs"``
    (leave one run out) or ``"time blocks"``."""
    if folds is not None:
        return [(np.asarray(tr)[pick], np.asarray(te)[pick]) for tr, te in folds], "given"
    if copy.n_runs > 1:
        log(f"cross-validation: leave one run out ({copy.n_runs} runs)")
        return run_folds(copy.t, copy.lengths, rules.blocks), "runs"
    return time_block_folds(copy.t, rules.blocks, rules.folds), "time blocks"


def _result(rounds, baseline, steps, base_res, full, search, finding, by, runs, model_name,
            how, derivatives, log) -> Diagnosis:
    rankings = [[_candidate(o, r.current, o is r.added) for o in _by_gain(r.options)]
                for r in rounds]
    final = steps[-1].fit.fit_model if steps else base_res.fit_model
    warnings = {"baseline": _plausible(base_res.fit_model, full)}
    if steps:
        warnings["final"] = _plausible(final, full)
    trials = [{"round": i, "effects": list(o.names), **_scores(o),
               "held_out_share_shown": _or_none(o.lower),
               "block_folds": o.block_folds, "block_ref": o.block_ref,
               "block_gains": o.block_gains, "physical": not o.physical,
               "converged": not o.unconverged, "fold_fits_at_limit": o.cut or None,
               "added": o is r.added, "start": o.start or None,
               "other_starts": [{"start": x.start, **_scores(x)} for x in o.rivals]}
              for i, r in enumerate(rounds) for o in r.options]
    if finding:
        log(finding)
    return Diagnosis(baseline=baseline, steps=steps, rankings=rankings,
                     holdout=np.zeros(full.t.size, bool), model=run_model(final, None),
                     model_name=model_name, velocity=how,
                     warnings={k_: w for k_, w in warnings.items() if w}, trials=trials,
                     search=search, finding=finding, folds=by, runs=runs,
                     derivatives=derivatives)

def _plausible(model, full: Data) -> list[str]:
    """`fitting._plausibility.plausibility` of `model` on each run (flags once each)."""
    flags: list[str] = []
    for d in full.runs():
        flags += [f for f in plausibility(model, d.t, d.x, d.v, d.F, a=d.a, load=d.load)
                  if f not in flags]
    return flags
