"""The diagnosis's decision: which effects to add, judged by full refits and blocked
cross-validation, with one rule (`fitting._rules.DiagnosisRules`).

**Options.** Every candidate effect of `jaxfric.effects` with a linear parameter is an
option, and so is a richer base model (`base_options`: a GMS with more elements), which
says "the base model is the limit here" when it wins. All effects sit in one *superset*
model (``plain + every candidate``, each switched off by its linear parameters at 0,
``param(..., linear=True)``), so every refit fits the same compiled program; an option
switches its effect on by freeing its parameters (the free set is data, not structure).
Its Jacobian is computed over the free coordinates only (``fit_datasets(..., narrow=True)``:
slots of 8, one program per width; the same fit, at about half the cost per step where
most of the superset is held).

**Each round** (forward selection):

1. each option is fitted jointly with the current model to convergence on every sample:
   its nonlinear parameters start at the grid point (`AbstractEffect.grid`) whose term
   best regresses the current residual, its linear ones at that regression's values, the
   rest of the model at the current fit; a base-model option from its own start
   (`_replaced`), in later rounds from its own fit of the round before with the current
   model's effects at their fitted values (it starts where it ended, the effect just
   added included);
2. an option whose refit removes no more training SSE than ``2 q s^2`` (`_optimism`: what
   q added coordinates remove when they fit only noise) is not cross-validated; of the
   others, the `tried` with the lowest training error are: refitted with each fold held
   out in turn (`folds`, a plain list of ``(train_weights, test_weights)``;
   `time_block_folds` makes the default), each from the current model's own fit on that
   fold's training samples, its grid start picked again on those samples
   (`Fitter.cross_validate_nested`); a base-model option, which does not contain the
   current model, is refitted from its own start (`Fitter.cross_validate`);
3. an option qualifies when ``log(SSE_current / SSE_option)`` of the held-out samples,
   block by block (each contiguous run of a fold's test samples is a block), has a mean
   above `z` standard errors (`block_z`; the blocks of one fold counted as one piece of
   evidence where they move together, `standard_error`), every fitted
   parameter is in its physical range (``param(..., physical=(lo, hi))``) and its fit on
   every sample ended by a rule of its own (`_converged`); of those that qualify, the
   one with the largest held-out gain is added (``z`` decides whether an option
   qualifies, the held-out error which is added: forward selection by cross-validated
   error; an effect that predicts more of the held-out error is not pushed out by one
   that predicts less, more evenly). The physical range and the convergence are checked
   first: an option that fails either is not cross-validated (it cannot qualify). Fold fits
   are compared at equal effort (`Fitter.reference`); one stopped at its step limit is
   judged where it stopped;
4. when none qualifies, the pairs of the options tested are refitted and judged the same.

The round repeats until nothing qualifies or `max_added` are in.
"""

import dataclasses
import itertools
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import numpy as np
import optimistix as optx

from jaxfric._fields import parameter_info

from . import _params
from ._candidates import _linear, _off, _signals, Data, physical, start_effect, switchable
from ._data import Dataset
from ._fit import fit_datasets
from ._per_run import shifted, with_runs
from ._rules import DiagnosisRules
from ._transforms import Identity, ParamProps


def time_block_folds(t, blocks: int, folds: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(train_weights, test_weights)]`` of `folds` folds: `blocks` contiguous time
    blocks of equal duration, block ``b`` held out in fold ``b % folds``."""
    t = np.asarray(t, float)
    b = np.minimum((blocks * (t - t[0]) / (t[-1] - t[0])).astype(int), blocks - 1)
    return [((b % folds != k).astype(float), (b % folds == k).astype(float))
            for k in range(folds)]


def run_folds(t, lengths, blocks: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Leave one run out: ``[(train_weights, test_weights)]``, fold ``k`` holding out run
    ``k`` (``lengths[k]`` samples, runs concatenated in order in `t`); the held-out run is
    cut into ``max(2, ceil(blocks / runs))`` time blocks of equal duration, numbered
    1, 2, ... in its test weights (each a block of the rule, `_blocks`)."""
    t = np.asarray(t, float)
    per = max(2, -(-blocks // len(lengths)))
    ends = np.cumsum(lengths)
    out = []
    for n, end in zip(lengths, ends):
        run = slice(int(end - n), int(end))
        tr, test = np.ones(t.size), np.zeros(t.size)
        tr[run] = 0.0
        u = t[run] - t[run][0]
        test[run] = 1 + np.minimum((per * u / max(u[-1], 1e-300)).astype(int), per - 1)
        out.append((tr, test))
    return out


def _blocks(folds) -> list[tuple[int, np.ndarray]]:
    """``(fold, sample indices)`` of every block of each fold's test samples: a contiguous
    stretch of test weights > 0 of one value (`run_folds` numbers the blocks of a run)."""
    out = []
    for k, (_, test) in enumerate(folds):
        test = np.asarray(test)
        idx = np.flatnonzero(test > 0)
        cut = np.flatnonzero((np.diff(idx) > 1) | (np.diff(test[idx]) != 0)) + 1
        for run in np.split(idx, cut):
            if run.size:
                out.append((k, run))
    return out


@dataclasses.dataclass
class Option:
    """One thing the rule can add: `names` (effect names, or the base model's name),
    its start `model`, which superset slots it frees (`on`), and what fitting found."""

    names: tuple[str, ...]
    model: object
    on: frozenset
    base: bool = False  # a base-model change (the plain model replaced)
    fitted: object = None
    result: object = None  # the `FitResult` of the fit on all samples
    pred: np.ndarray | None = None
    sse: float = np.inf  # training SSE on all samples
    gain: float = np.nan  # held-out SSE removed, share of the current model's
    z: float = np.nan  # mean block gain over its standard error
    physical: str = ""  # "" when physical, else why not
    optimism: float = 0.0  # 2 q s^2: the training SSE any q added coordinates remove
    against: float = np.nan  # the training SSE of the model `optimism` is counted from
    fold_preds: list = dataclasses.field(default_factory=list)
    fold_models: list = dataclasses.field(default_factory=list)
    fold_converged: list = dataclasses.field(default_factory=list)
    fold_refs: list = dataclasses.field(default_factory=list)  # as a reference (`reference`)
    unconverged: str = ""  # "" when its fit on every sample converged, else why not
    cut: str = ""  # its fold fits stopped at their step limit (judged where they stopped)
    make: object = None  # a base-model option: how its plain model is made (`_replaced`)
    #: Why an option among those tried was not cross-validated ("" when it was, or was not
    #: among them): it cannot qualify (not physical, or its fit not converged).
    skipped: str = ""
    #: Per block of the rule (`_blocks`, in order): its fold, the held-out SSE the current
    #: model leaves in it and what this option removes from that (N^2; set by `judge`), so
    #: that other rules can be evaluated on a recorded run without refitting.
    block_folds: list = dataclasses.field(default_factory=list)
    block_ref: list = dataclasses.field(default_factory=list)
    block_gains: list = dataclasses.field(default_factory=list)

    def _note(self, what: str, res) -> None:
        if not _converged(res):
            self.unconverged += ("; " if self.unconverged else "") + f"{what}: {res.stopped}"

    def _fold(self, fitted, pred, res) -> None:
        self.fold_models.append(fitted)
        self.fold_preds.append(pred)
        self.fold_converged.append(_converged(res))
        if not _converged(res):
            self.cut += ("; " if self.cut else "") + (
                f"fold {len(self.fold_preds) - 1}: {res.stopped.split(';')[0]}")

    @property
    def name(self) -> str:
        return " + ".join(self.names)


def _converged(res) -> bool:
    """Whether a fit ended by a rule of its own, its values final: its stop kind
    (`FitResult.stop`) is ``"converged"``, or ``"kink"`` with a finite RMSE (its steps gain
    (next to) nothing although its linear model predicts more: a kink of the cost, a local
    minimum of the cost as it is; what that point predicts held out is for the rule to
    judge). Not a fit cut at its step limit (it would go on), a failed solve, a stuck one,
    or one failing `fit`'s own checks (R2, a parameter pinned at a bound)."""
    if bool(np.asarray(res.result == optx.RESULTS.successful)):
        return True
    return res.stop == "kink" and bool(np.isfinite(np.asarray(res.rmse)))


class Fitter:
    """Fits on one record (one run or several, `Data`): `superset` models, each with its
    own slots switched on."""

    def __init__(self, data: Data, fixed=(), max_steps: int = 300, log=None):
        self.data, self.fixed, self.max_steps = data, tuple(fixed), max_steps
        self.log = log or (lambda *_: None)

    def props(self, model, on: frozenset):
        """Free: the base model's leaves (but `fixed`) and those of the effects in `on`
        (indices into ``model.effects``); an effect's linear leaves on an `Identity`. A
        leaf `default_props` holds (a drift's level in a fit of one run) stays held."""
        fit_model = _params.to_fit_representation(model)
        effects = getattr(fit_model, "effects", ())
        plain = fit_model.without_effects() if effects else fit_model
        n_base = len(parameter_info(plain))
        owner = [-1] * n_base
        for i, e in enumerate(effects):
            owner += [i] * len(parameter_info(e))
        infos = parameter_info(fit_model)
        linear = [o >= 0 and info.name in _linear(effects[o]) for o, info in zip(owner, infos)]
        props = _params.props_leaves(_params.default_props(fit_model))
        leaves = [ParamProps(Identity() if lin else p.transform,
                             free=p.free and ((o < 0 and info.name not in self.fixed)
                                              or o in on))
                  for p, o, lin, info in zip(props, owner, linear, infos)]
        tree = jax.tree.structure(_params.default_props(fit_model),
                                  is_leaf=_params._is_props)
        return fit_model, jax.tree.unflatten(tree, leaves)

    def n_free(self, model, on: frozenset) -> int:
        """The number of free coordinates of `model` with the effects in `on` switched on
        (a per-run parameter counted once per run it is fitted for, as `fit` fits it)."""
        fit_model, props = self.props(with_runs(model, self.data.n_runs), on)
        sizes = [int(np.size(leaf)) for leaf in jax.tree.leaves(
            eqx.filter(fit_model, eqx.is_inexact_array))]
        return sum(n for n, p in zip(sizes, _params.props_leaves(props)) if p.free)

    def fit(self, model, on: frozenset, weights=None):
        """``(fitted model in the fit representation, prediction on every sample)``: one
        fit of every run at once (`fitting.fit_datasets`: each run from its own zero state,
        per-run parameters per run); a run of zero weight is left out of the fit and predicted with
        its per-run parameters at their mean over the runs fitted (`Data.simulate`)."""
        d = self.data
        runs = d.runs()
        w = ([None] * len(runs) if weights is None else
             [np.asarray(weights, float)[sl] for sl in d.slices()])
        fitted = [i for i, wi in enumerate(w) if wi is None or np.any(wi > 0)]
        model = with_runs(model, len(runs), reference=fitted[0])  # a level's reference
        fit_model, props = self.props(model, on)
        sets = [Dataset(t=runs[i].t, x=runs[i].x, F=runs[i].F, v=runs[i].v, a=runs[i].a,
                        load=runs[i].load, weights=w[i]) for i in fitted]
        res = fit_datasets(fit_model, shifted(sets, fitted) if len(runs) > 1 else sets,
                           props=props, max_steps=self.max_steps, narrow=True)
        if len(runs) == 1:
            res = eqx.tree_at(lambda r: (r.prediction, r.residuals), res,
                              (res.prediction[0], res.residuals[0]))
        self.last = res
        return res.fit_model, d.simulate(res.fit_model, fitted)

    def fold_fit(self, model, on: frozenset, train):
        """`fit` on a fold's training samples, continued once from where it stopped when
        it did not converge: the step budget of every fold fit."""
        fitted, pred = self.fit(model, on, train)
        if not _converged(self.last):
            fitted, pred = self.fit(fitted, on, train)
        return fitted, pred

    def cross_validate_nested(self, option: Option, current: Option, folds,
                              new: dict) -> None:
        """Refit `option` (the current model plus the effects `new`: slot index -> effect
        name) with each fold held out, starting from the current model's own fit on that
        fold's training samples, the new effects at their start picked on those samples
        only (`start_effect` on that fit's residual): nested and paired, so the held-out
        difference is the effects', not a different optimum of the base model's, and
        nothing was fitted on the held-out blocks."""
        if option.fold_preds:
            return
        for k, (train, _) in enumerate(folds):
            model = current.fold_models[k]
            resid = self.data.F - current.fold_preds[k]
            s = _signals(self.data, model.without_effects())
            for i, name in new.items():
                e = start_effect(name, self.data, None, resid, s, weights=train)
                model = eqx.tree_at(lambda m, i=i: m.effects[i], model, e)
            option._fold(*self.fold_fit(model, option.on, train), self.last)

    def reference(self, current: Option, folds) -> None:
        """Set `current.fold_refs`, what every option is judged against: per fold, the
        current model's fold fit, or where it stopped at its step limit, that fit continued
        with the budget each option gets from it (`fold_fit`). Equal effort: an option is
        not credited with the improvement a cut fit leaves, only with its own freedom."""
        if current.fold_refs:
            return
        for k, (train, _) in enumerate(folds):
            if current.fold_converged[k]:
                current.fold_refs.append(current.fold_preds[k])
            else:
                self.log(f"  continuing the current model's fold {k} fit (stopped at its "
                         "step limit) as the reference ...")
                current.fold_refs.append(self.fold_fit(current.fold_models[k], current.on,
                                                       train)[1])

    def cross_validate(self, option: Option, folds, current: Option | None = None) -> None:
        """Refit `option` from its start (`option.model`) with each fold held out; a
        base-model option made from the current model (`Option.make`) from the one made
        from `current`'s fit on that fold's training samples (nested and paired, as
        `cross_validate_nested`). Not from its fit on all samples: a fit started at an
        optimum can stop at once (the solver's tolerance test), leaving the held-out
        blocks predicted by a model that was fitted on them."""
        if option.fold_preds:
            return
        for k, (train, _) in enumerate(folds):
            start = (_replaced(option.make, current.fold_models[k])
                     if option.make is not None and current is not None else option.model)
            option._fold(*self.fold_fit(start, option.on, train), self.last)


def judge(option: Option, current: Option, folds, F: np.ndarray) -> None:
    """Set `option`'s held-out gain over `current` (share of the current model's held-out
    SSE) and ``z``: the mean block gain over its standard error. The current model's
    held-out predictions are its `fold_refs` when set (`Fitter.reference`)."""
    ref = current.fold_refs or current.fold_preds
    option.block_folds, option.block_ref, option.block_gains = [], [], []
    for k, idx in _blocks(folds):
        r0 = ref[k][idx] - F[idx]
        r1 = option.fold_preds[k][idx] - F[idx]
        option.block_folds.append(k)
        option.block_ref.append(float(r0 @ r0))
        option.block_gains.append(float(r0 @ r0 - r1 @ r1))
    d = np.asarray(option.block_gains)
    total = float(np.sum(option.block_ref))
    option.gain = float(d.sum() / total) if total > 0 else 0.0
    option.z = block_z(option.block_ref, option.block_gains, option.block_folds)


def block_z(ref, gains, folds) -> float:
    """The rule's statistic: the mean over blocks of ``log(SSE_current / SSE_option)``
    (held out, block by block), over its standard error (`standard_error`)."""
    ref = np.maximum(np.asarray(ref, float), np.finfo(float).tiny)
    new = np.maximum(ref - np.asarray(gains, float), np.finfo(float).tiny)
    r = np.log(ref / new)
    se = standard_error(r, np.asarray(folds))
    return float(r.mean() / se) if se > 0 else (np.inf if r.mean() > 0 else 0.0)


def standard_error(gains: np.ndarray, folds: np.ndarray) -> float:
    """The standard error of the mean block gain: the larger of (a) the blocks taken as
    independent (their standard deviation over sqrt(B)) and (b) the blocks of one fold
    taken together (the cluster-robust standard error of the mean, by fold sums, with its
    small-sample factor K/(K-1)). The blocks of a fold share one fitted model, so an
    error of that fit (parameters bent by that fold's training data) moves them together;
    (b) carries it, (a) does not. Balanced, (b)^2 is the one-way ANOVA's between-fold mean
    square over B, so the larger of the two is the random-effects estimate of the
    variance of the mean with the between-fold variance truncated at 0. Infinite for one
    block."""
    d, f = np.asarray(gains, float), np.asarray(folds)
    B = d.size
    if B < 2:
        return np.inf
    independent = np.std(d, ddof=1) / np.sqrt(B)
    ks = np.unique(f)
    if ks.size < 2:
        return float(independent)
    dev = np.array([np.sum(d[f == k] - d.mean()) for k in ks])
    clustered = np.sqrt(ks.size / (ks.size - 1) * np.sum(dev**2)) / B
    return float(max(independent, clustered))


def held_out_sse(option: Option, folds, F: np.ndarray) -> float:
    """The held-out SSE of `option` over all folds (N^2; every sample held out once)."""
    return float(sum(np.sum((option.fold_preds[k] - F)[idx] ** 2) for k, idx in _blocks(folds)))


@dataclasses.dataclass
class Round:
    """One round: every option fitted (`options`, best training fit first), the one added
    (None when nothing qualified), and the current model's held-out SSE."""

    options: list[Option]
    added: Option | None
    current: Option


def select(fitter: Fitter, start, candidates: Sequence[str], folds, rules: DiagnosisRules,
           base_options: Callable[[], list] = lambda: [], log=None) -> list[Round]:
    """Forward selection from model `start` (plain) over effect names `candidates` and the
    base models `base_options()` gives (``[(name, plain model or maker)]``, `_replaced`);
    see the module docstring. Returns the rounds; the last round's ``current`` is the
    final model."""
    log = log or (lambda *_: None)
    data = fitter.data
    names = [n for n in candidates if switchable(n)]
    plain = _params.to_fit_representation(start)
    slots = [_off(data.grid(n)[0]) for n in names]
    superset = plain + tuple(slots)
    log(f"fitting the base model ({len(names)} candidate effects held at 0) ...")
    fitted, pred = fitter.fit(superset, frozenset())
    current = Option(("base",), superset, frozenset(), fitted=fitted, pred=pred,
                     result=fitter.last,
                     sse=float(np.sum((pred - data.F) ** 2)))
    rounds, switched = [], False
    earlier = {}  # base-model option name -> its plain model fitted in the round before
    while len(rounds) < rules.max_added:
        resid = data.F - current.pred
        signals = _signals(data, current.fitted.without_effects())
        options = []
        for i, n in enumerate(names):
            if i in current.on:
                continue
            eff = start_effect(n, data, None, resid, signals)
            model = eqx.tree_at(lambda m, i=i: m.effects[i], current.fitted, eff)
            options.append(Option((n,), model, current.on | {i}))
        if not switched:
            for bname, make in base_options():
                options.append(Option((bname,), _replaced(earlier.get(bname, make),
                                                          current.fitted),
                                      current.on, base=True, make=make))
        for o in options:
            _refit(fitter, o, current, log)
        options.sort(key=lambda o: o.sse)
        _optimism(fitter, current, options)
        best = [o for o in options if o.sse < current.sse - o.optimism][:rules.tried]
        chosen = _cross_validate(fitter, current, best, folds, rules, log)
        if chosen is None and len(rounds) + 2 <= rules.max_added:
            singles = [o for o in best if not o.base]
            pairs = [(_pair(a, b, current), min(a, b, key=lambda o: o.sse))
                     for a, b in itertools.combinations(singles, 2)]
            for o, _ in pairs:
                _refit(fitter, o, current, log)
            for o, single in pairs:  # what its other effect adds to its better single
                _optimism(fitter, single, [o])
            options += [o for o, _ in pairs]
            chosen = _cross_validate(fitter, current, [o for o, _ in pairs
                                                       if o.sse < o.against - o.optimism],
                                     folds, rules, log)
        rounds.append(Round(options, chosen, current))
        if chosen is None:
            break
        earlier = {o.name: _plain(o.fitted) for o in options
                   if o.base and o.fitted is not None and _finite(o.fitted)}
        switched |= chosen.base
        current = chosen
    return rounds


def _plain(model):
    """`model` without its effects."""
    return model.without_effects() if getattr(model, "effects", ()) else model


def _finite(model) -> bool:
    return all(bool(np.all(np.isfinite(np.asarray(leaf)))) for leaf in
               jax.tree.leaves(eqx.filter(model, eqx.is_inexact_array)))


def _replaced(make, model):
    """`model` (a fit with its effects) with its plain model replaced by `make`: a plain
    model, or a function of the fitted plain model that returns one (a richer model that
    starts where the fit is, `fitting._start.gms_like`)."""
    effects = tuple(getattr(model, "effects", ()))
    plain = model.without_effects() if effects else model
    new = _params.to_fit_representation(make if isinstance(make, eqx.Module) else make(plain))
    return new + effects if effects else new


def _refit(fitter: Fitter, o: Option, current: Option, log) -> None:
    """Fit option `o` on every sample; set its fit, training SSE and physical check."""
    log(f"  refitting with {o.name} ...")
    o.fitted, o.pred = fitter.fit(o.model, o.on)
    o.result = fitter.last
    o._note("fit on every sample", o.result)
    o.sse = float(np.sum((o.pred - fitter.data.F) ** 2))
    o.physical = "" if o.base else "; ".join(
        p for i in sorted(o.on - current.on) if (p := physical(o.fitted.effects[i])))


def _optimism(fitter: Fitter, current: Option, options: list[Option]) -> None:
    """Set each option's `optimism`, ``2 q s^2``: how much q added free coordinates lower
    the training SSE in expectation when they fit only noise (Mallows' Cp, AIC), with
    ``s^2`` the current model's training SSE over its residual degrees of freedom. An
    option whose refit removes no more than that cannot be expected to predict held-out
    data better, and is not cross-validated."""
    n = int(np.sum(np.isfinite(fitter.data.F)))
    p = fitter.n_free(current.model, current.on)
    s2 = current.sse / max(n - p, 1)
    for o in options:
        q = max(fitter.n_free(o.model, o.on) - p, 1)
        o.optimism, o.against = 2.0 * q * s2, current.sse


def _pair(a: Option, b: Option, current: Option) -> Option:
    """Options `a` and `b` (singles) switched on together, from their starts."""
    (j,) = b.on - current.on
    model = eqx.tree_at(lambda m: m.effects[j], a.model, b.model.effects[j])
    return Option(a.names + b.names, model, a.on | b.on)


def _cross_validate(fitter, current, options, folds, rules, log):
    """Cross-validate `current` and `options`; the qualifying one of largest held-out
    gain. An option that cannot qualify whatever its held-out error (its fit on every
    sample not physical or not converged: both known before the folds are fitted) is not
    cross-validated (`Option.skipped` says why): the decision is the same, without its
    fold fits."""
    fitter.cross_validate(current, folds)
    fitter.reference(current, folds)
    for o in options:
        if o.physical or o.unconverged:
            o.skipped = "; ".join(
                w for w in (o.physical and f"not physical: {o.physical}",
                            o.unconverged and f"not converged: {o.unconverged}") if w)
            log(f"  {o.name}: not cross-validated, it cannot qualify ({o.skipped})")
            continue
        log(f"  cross-validating {o.name} ({len(folds)} folds) ...")
        names = {i: type(o.model.effects[i]).name for i in o.on - current.on}
        if names and not o.base:
            fitter.cross_validate_nested(o, current, folds, names)
        else:
            fitter.cross_validate(o, folds, current)
        judge(o, current, folds, fitter.data.F)
        log(f"    held-out SSE {-100 * o.gain:+.3g} %, z = {o.z:.2f}"
            + (f" (not physical: {o.physical})" if o.physical else "")
            + (f" (not converged: {o.unconverged})" if o.unconverged else "")
            + (f" (judged where stopped: {o.cut})" if o.cut else ""))
    # An option whose fit on every sample did not converge has no final values to check
    # or add; its fold fits are evidence at equal effort (`Fitter.reference`).
    good = [o for o in options if o.z >= rules.z and not o.physical and not o.unconverged]
    return max(good, key=lambda o: o.gain) if good else None
