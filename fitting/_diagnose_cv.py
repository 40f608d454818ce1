"""`diagnose_cv`: the diagnosis by full refits and blocked cross-validation, with one rule
(`fitting._select`, thresholds in `fitting._rules.DiagnosisRules`), returning the same
`fitting.Diagnosis` as `fitting.diagnose`.

A long record (at least twice `search_samples` samples) is searched on one sample in
``k = n // search_samples`` (the full-rate velocity and acceleration estimates at those
samples, so an effect's relation to them is kept); the baseline and the final model are
then refitted on every sample from where the search left them, and the errors of those
refits are reported (the held-out errors are the search's cross-validation).
"""

from collections.abc import Callable, Sequence

import numpy as np

from ._candidates import _code, Candidate
from ._derivatives import describe, estimate_acceleration, estimate_derivatives
from ._diagnose import Diagnosis
from ._diagnose_context import _contained, effect_names, Step
from ._fit import fit
from ._params import to_fit_representation
from ._plausibility import plausibility
from ._regimes import regime_errors, regimes
from ._rules import DiagnosisRules
from ._select import Data, Fitter, held_out_sse, Option, select, time_block_folds
from ._start import initial_model


#: A record of at least twice this many samples is searched on about this many.
SEARCH_SAMPLES = 5_000


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
    why = (f"refit removes {100 * (1 - o.sse / current.sse):.3g} % of the training SSE"
           + (f"; held out {100 * o.gain:.3g} % of the SSE, z = {o.z:.2f}" if judged else
              "; not cross-validated (not among the best training fits)")
           + (f"; not physical: {o.physical}" if o.physical else ""))
    if effect is not None:
        why = f"{effect.describe()}; {why}"
    return Candidate(name=o.name, effect=effect, score=float(o.gain if judged else np.nan),
                     t_stat=float(o.z), significant=added, evidence=why,
                     code=_code(effect) if effect is not None else f"base model {o.name}")


def diagnose_cv(
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
    """Fit `model` to ``(t, x, F[, v])`` (SI) and add the missing effects that the blocked
    cross-validation of full refits supports (`fitting._select`).

    `rules`: the thresholds (`DiagnosisRules`). `folds`: ``[(train_weights,
    test_weights)]`` over the samples (default: `time_block_folds` of `rules`), e.g. one
    fold per run for a leave-one-run-out diagnosis. `base_models`: ``[(name, plain
    model)]`` tried as replacements of the base model by the same rule (default none);
    when one is added the diagnosis says that the base model is the limit. Other
    arguments as for `fitting.diagnose`.
    """
    log = log or (lambda *_: None)
    rules = DiagnosisRules() if rules is None else rules
    given_v = v is not None
    t, x, F = (np.asarray(arr, np.float64) for arr in (t, x, F))
    how = describe(derivatives, velocity_window, column=v is not None,
                   acceleration_column=a is not None)
    if v is None:
        v, a_est = estimate_derivatives(t, x, derivatives, velocity_window)
    else:
        v = np.asarray(v, np.float64)
        a_est = estimate_acceleration(t, v, derivatives, velocity_window)
    a = a_est if a is None else np.asarray(a, np.float64)
    full = Data(t, x, np.asarray(v, np.float64), F, a,
                None if load is None else np.asarray(load, np.float64))
    k = t.size // search_samples if search_samples and t.size >= 2 * search_samples else 1
    pick = slice(None, None, k)
    copy = Data(*(None if arr is None else arr[pick] for arr in
                  (full.t, full.x, full.v, full.F, full.a, full.load)))
    search = (f"effects searched on one sample in {k} ({copy.t.size} samples); the baseline "
              f"and final model refitted on all {t.size}") if k > 1 else ""
    if search:
        log(search)
    folds = (time_block_folds(copy.t, rules.blocks, rules.folds) if folds is None else
             [(np.asarray(tr)[pick], np.asarray(te)[pick]) for tr, te in folds])
    model = to_fit_representation(model)
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
    rankings = [[_candidate(o, r.current, o is r.added) for o in r.options] for r in rounds]
    final = steps[-1].fit.fit_model if steps else base_res.fit_model
    warnings = {"baseline": plausibility(base_res.fit_model, full.t, full.x, full.v, full.F,
                                         a=full.a, load=full.load)}
    if steps:
        warnings["final"] = plausibility(final, full.t, full.x, full.v, full.F, a=full.a,
                                         load=full.load)
    trials = [{"round": i, "effects": list(o.names), "sse_train": o.sse,
               "held_out_share_removed": None if not np.isfinite(o.gain) else o.gain,
               "z": None if not np.isfinite(o.z) else o.z, "physical": not o.physical,
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
