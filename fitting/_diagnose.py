"""`diagnose`: fit a model, then add the missing physical effects that full refits and
blocked cross-validation support, with one rule (the decision is `fitting._select`, its
thresholds `fitting.DiagnosisRules`; docs/diagnosis.md explains it).

What is searched (`effect_names`): every effect of `jaxfric.effects` with a linear
parameter not already in the model (those of an angle only on rotary data, those of a load
only with a load signal), and a richer base model (a GMS with 20 elements).

A long record (at least twice `search_samples` samples) is searched on one sample in
``k = n // search_samples``, halved until that copy is faithful (`_faithful_step`: the
start model simulated on it is within the force's noise of its full-rate simulation). The
copy keeps the full-rate velocity and acceleration estimates at its samples, so an
effect's relation to them is kept; the force is not averaged, which would smear short
accelerations. The baseline and the final model are then refitted on every sample from
where the search left them, and the errors of those refits are reported (the held-out
errors are the search's cross-validation).
"""

from collections.abc import Callable, Sequence

import numpy as np

from jaxfric import effects as fx

from ._candidates import _code, Candidate
from ._data import check_dataset, Dataset
from ._derivatives import describe, estimate_acceleration, estimate_derivatives
from ._diagnosis import Diagnosis, Step
from ._fit import fit
from ._params import leaf_names, to_fit_representation
from ._plausibility import plausibility
from ._regimes import regime_errors, regimes
from ._rules import DiagnosisRules
from ._select import Data, Fitter, held_out_sse, Option, select, time_block_folds
from ._start import initial_model


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


def _subsample(full: Data, k: int) -> Data:
    return Data(*(None if arr is None else arr[::k] for arr in
                  (full.t, full.x, full.v, full.F, full.a, full.load)))


def _faithful_step(full: Data, model, k: int, log) -> tuple[int, str]:
    """The largest of ``k, k // 2, ..., 1`` whose search copy (one sample in k) is
    faithful: the start `model` simulated on the copy differs from it simulated on every
    sample (at the copy's samples) by at most the force's noise (`noise_level`), RMS. A
    state model integrates its presliding and lag over each sampling step, so a coarser
    copy is another discretisation: where moves start and stop within a few samples, its
    error can exceed every effect sought, and would be judged as the base model's
    mismatch. Returns k and what was measured, in words."""
    if k <= 1:
        return 1, ""
    sigma = noise_level(full.F)
    ref = full.simulate(model)
    words = ""
    while k > 1:
        err = float(np.sqrt(np.mean((_subsample(full, k).simulate(model) - ref[::k]) ** 2)))
        if err <= sigma:
            return k, (f"{words}its simulation differs from the full-rate one by {err:.2g} N "
                       f"RMS, within the force's noise, {sigma:.2g} N")
        words += f"one sample in {k} would change the simulation by {err:.2g} N RMS; "
        log(f"one sample in {k} would change the start model's simulation by {err:.2g} N "
            f"RMS, more than the force's noise ({sigma:.2g} N): a denser copy")
        k //= 2
    return 1, (f"not subsampled: {words.rstrip('; ')}, more than the force's noise "
               f"({sigma:.2g} N)")


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
    fit_model, props = f.props(pruned, frozenset(range(len(getattr(pruned, "effects", ())))))
    return fit(fit_model, full.t, full.x, full.F, full.v, props=props, max_steps=f.max_steps,
               load=full.load, a=full.a)


def _step(res, added, full: Data, holdout_rmse: float, masks) -> Step:
    resid = np.asarray(res.prediction) - full.F
    return Step(added=list(added), fit=res, rmse=float(np.sqrt(np.mean(resid**2))),
                rmse_holdout=holdout_rmse, regimes=regime_errors(-resid, masks),
                rel_error=float(np.sqrt(np.mean(resid**2) / np.mean(full.F**2))))


def _candidate(o: Option, current: Option, added: bool) -> Candidate:
    new = sorted(o.on - current.on)
    effect = o.fitted.effects[new[0]] if new else None
    judged = np.isfinite(o.z)
    worth = o.sse < current.sse - o.optimism
    why = (f"refit removes {100 * (1 - o.sse / current.sse):.3g} % of the training SSE"
           + (f"; held out {100 * o.gain:.3g} % of the SSE, z = {o.z:.2f}" if judged else
              "; not cross-validated (not among the best training fits)" if worth else
              "; not cross-validated (no more than fitting noise removes, 2 q s^2)")
           + (f"; not physical: {o.physical}" if o.physical else "")
           + (f"; not converged (no evidence): {o.unconverged}" if o.unconverged else ""))
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


def diagnose(
    model, t, x, F, v=None, *,
    effects: Sequence[str] | None = None,
    rules: DiagnosisRules | None = None,
    folds=None,
    base_models: Sequence[tuple[str, object]] | None = None,
    max_steps: int = 150,
    fixed: Sequence[str] = (),
    model_name: str | None = None,
    derivatives: str = "central",
    velocity_window: float | None = None,
    log: Callable[[str], None] | None = None,
    rotary: bool = False,
    load=None,
    search_samples: int | None = SEARCH_SAMPLES,
    a=None,
) -> Diagnosis:
    """Fit `model` to ``(t, x, F[, v])`` (SI) and add, one round at a time, the missing
    effect that full refits and blocked cross-validation support (`fitting._select`;
    docs/diagnosis.md).

    - `rules`: the thresholds (`DiagnosisRules`, every one documented there).
    - `folds`: ``[(train_weights, test_weights)]`` over the samples (default: the time
      blocks of `rules`, `fitting._select.time_block_folds`), e.g. one fold per run for a
      leave-one-run-out diagnosis; each contiguous stretch of a fold's held-out samples is
      then a block of the rule.
    - `effects`: names from `jaxfric.effects.EFFECTS` to search (default `effect_names`:
      every effect not already in the model, nor one of its free parameters: ``viscous``
      only when ``sigma2`` is held with `fixed`; the effects of an angle only when
      `rotary`, `x` then an angle in rad; those of the load only with `load`).
    - `base_models`: ``[(name, plain model)]`` tried as replacements of the base model by
      the same rule (default: a GMS with 20 elements; ``()`` for none); when one is
      added, ``Diagnosis.finding`` says that the base model is the limit here.
    - `fixed`: parameter names of `model` held at their values in every fit.
    - `max_steps`: per fit. `load`: the transmitted load (N, or N m), for the load effects.
    - `derivatives`, `velocity_window`: how the velocity is estimated from the position
      when `v` is not given (``"central"``, ``"savgol"`` or ``"backward"``,
      `fitting._derivatives`), and the acceleration `jaxfric.effects.Inertia` reads by the
      same method, unless `a` (m/s^2) is given.
    - `search_samples`: a record of at least twice as many samples is searched on about
      this many (one sample in k) and the baseline and final model refitted on all; None or
      0 searches on every sample.
    - `log`: called with a line of progress for every fit.

    Returns a `Diagnosis`; its models are in the fit representation
    (`fitting.to_fit_representation`).
    """
    log = log or (lambda *_: None)
    rules = DiagnosisRules() if rules is None else rules
    given_v = v is not None
    full, how = _record(t, x, F, v, a, load, derivatives, velocity_window)
    t = full.t
    k = t.size // search_samples if search_samples and t.size >= 2 * search_samples else 1
    k, faithful = _faithful_step(full, model, k, log)
    pick = slice(None, None, k)
    copy = _subsample(full, k)
    search = (f"effects searched on one sample in {k} ({copy.t.size} samples; {faithful}); "
              f"the baseline and final model refitted on all {t.size}") if k > 1 else faithful
    if search:
        log(search)
    folds = (time_block_folds(copy.t, rules.blocks, rules.folds) if folds is None else
             [(np.asarray(tr)[pick], np.asarray(te)[pick]) for tr, te in folds])
    model = to_fit_representation(model)
    unknown = set(fixed) - set(leaf_names(model))
    if unknown:
        raise ValueError(f"fixed: {type(model).__name__} has no parameter(s) "
                         f"{sorted(unknown)}; it has {leaf_names(model)}")
    present = {e.name for e in getattr(model, "effects", ())}
    names = effect_names(effects, present | _contained(model, tuple(fixed)) if not effects
                         else present, rotary, load is not None)
    fitter = Fitter(copy, fixed, max_steps, log)
    if base_models is None:
        base_models = [("GMS with 20 elements",
                        initial_model("gms", copy.t, copy.x, copy.F, copy.v, n_elements=20))]
    rounds = select(fitter, model, names, folds, rules,
                    base_options=lambda: list(base_models), log=log)
    masks = regimes(full.t, full.x, full.v)
    n_copy = copy.t.size

    def cv_rmse(o):
        return float(np.sqrt(held_out_sse(o, folds, copy.F) / n_copy)) if o.fold_preds \
            else float("nan")

    first = rounds[0].current
    base_res = _final_fit(fitter, first.fitted, first.on, copy, full, log, "the baseline")
    baseline = _step(base_res, [], full, cv_rmse(first), masks)
    steps, added, finding = [], [], ""
    chosen = [r.added for r in rounds if r.added is not None]
    for i, o in enumerate(chosen):
        added = [*added, *o.names]
        if o.base:
            finding = (f"the base model is the limit here: {o.name} predicts the held-out "
                       f"blocks better ({100 * o.gain:.3g} % of their SSE, z = {o.z:.2f}) "
                       "than any effect added to the base model")
        res = (_final_fit(fitter, o.fitted, o.on, copy, full, log, " + ".join(added))
               if i == len(chosen) - 1 else o.result)
        steps.append(_step(res, added, full if i == len(chosen) - 1 else copy,
                           cv_rmse(o), masks if i == len(chosen) - 1 else
                           regimes(copy.t, copy.x, copy.v)))
    rankings = [[_candidate(o, r.current, o is r.added) for o in _by_gain(r.options)]
                for r in rounds]
    final = steps[-1].fit.fit_model if steps else base_res.fit_model
    warnings = {"baseline": plausibility(base_res.fit_model, full.t, full.x, full.v, full.F,
                                         a=full.a, load=full.load)}
    if steps:
        warnings["final"] = plausibility(final, full.t, full.x, full.v, full.F, a=full.a,
                                         load=full.load)
    trials = [{"round": i, "effects": list(o.names), "sse_train": o.sse,
               "held_out_share_removed": None if not np.isfinite(o.gain) else o.gain,
               "z": None if not np.isfinite(o.z) else o.z, "physical": not o.physical,
               "converged": not o.unconverged,
               "added": o is r.added} for i, r in enumerate(rounds) for o in r.options]
    if finding:
        log(finding)
    return Diagnosis(baseline=baseline, steps=steps, rankings=rankings,
                     holdout=np.zeros(t.size, bool), model=final,
                     model_name=model_name or type(model).__name__, velocity=how,
                     warnings={k_: w for k_, w in warnings.items() if w}, trials=trials,
                     search=search, finding=finding,
                     derivatives=None if given_v else {"method": derivatives,
                                                             "window_s": velocity_window})
