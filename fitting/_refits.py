"""How the diagnosis fits its options (`fitting._select` decides with what they give):
`Option`, one thing the rule can add, with what its fits found, and `Fitter`, the fits on
one record: the superset model with some effects switched on (their parameters freed), on
every sample or on a fold's training samples, nested and paired with the current model's
fold fits. `_converged` says which fits the rule takes as final."""

import contextlib
import dataclasses
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import numpy as np
import optimistix as optx

from jaxfric._fields import parameter_info

from . import _params
from ._candidates import _linear, _signals, Data, start_effect
from ._data import Dataset
from ._fit import fit_datasets
from ._per_run import shifted, with_runs
from ._transforms import Identity, ParamProps


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
    lower: float = np.nan  # the held-out gain shown at z standard errors (`lower_gain`)
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
    start: str = ""  # a base-model option: which of its starts gave the fit kept
    #: Added: the other qualifying options it is not shown better than, ``(name, z)``.
    ties: list = dataclasses.field(default_factory=list)
    #: A base-model option: its other starts, fitted on every sample, cross-validated
    #: with it; the one of most held-out gain is kept (`fitting._select._held_out_race`).
    rivals: list = dataclasses.field(default_factory=list)
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

    def __init__(self, data: Data, fixed=(), max_steps: int = 300, log=None,
                 workers: int | None = None):
        self.data, self.fixed, self.max_steps = data, tuple(fixed), max_steps
        self.log = log or (lambda *_: None)
        self.workers = default_workers() if workers is None else max(1, int(workers))
        self._local = threading.local()

    @property
    def last(self):
        """The `FitResult` of this thread's latest fit."""
        return self._local.last

    @last.setter
    def last(self, res) -> None:
        self._local.last = res

    def map(self, fun, items) -> list:
        """``[fun(item) for item in items]``, up to `workers` at a time in threads, in
        order. The fits are independent and each is deterministic, so the results are
        those of the loop; JAX runs compiled code without Python's lock, and one thread's
        Python work between compiled chunks overlaps another's computation. An exception
        (Ctrl-C included) cancels the calls not begun and is raised at once; those running
        end in the background, their results dropped."""
        items = list(items)
        if self.workers <= 1 or len(items) <= 1:
            return [fun(item) for item in items]
        pool = ThreadPoolExecutor(min(self.workers, len(items)), "jaxfric-fit")
        try:
            return [f.result() for f in [pool.submit(fun, item) for item in items]]
        finally:
            pool.shutdown(wait=False, cancel_futures=True)

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

    def compile_ahead(self, makers) -> list[threading.Thread]:
        """Compile, each in a thread of its own, the programs of the fits to come of the
        models `makers` make (functions of no argument returning ``(model, on)``): a fit
        of no step of each (`fitting.fit_datasets` with ``max_steps=0``: one evaluation of
        its start with the fit's own programs), its result dropped; the fit to come then
        finds them compiled. For programs that cannot be made earlier (a base-model
        option's, made while the base model is fitted, when a core is free); join the
        threads before those fits, which would otherwise compile the same programs again.
        Nothing with one worker (`workers`); an error is left for the fit to come."""
        if self.workers <= 1:
            return []

        def run(make):
            with contextlib.suppress(Exception):
                self.fit(*make(), steps=0)

        threads = [threading.Thread(target=run, args=(make,), name="jaxfric-compile",
                                    daemon=True) for make in makers]
        for thread in threads:
            thread.start()
        return threads

    def fit(self, model, on: frozenset, weights=None, steps: int | None = None):
        """``(fitted model in the fit representation, prediction on every sample)``: one
        fit of every run at once (`fitting.fit_datasets`: each run from its own zero state,
        per-run parameters per run), `steps` (default `max_steps`) steps at most; a run of
        zero weight is left out of the fit and predicted with its per-run parameters at
        their mean over the runs fitted (`Data.simulate`)."""
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
                           props=props, max_steps=self.max_steps if steps is None else steps,
                           narrow=True)
        if len(runs) == 1:
            res = eqx.tree_at(lambda r: (r.prediction, r.residuals), res,
                              (res.prediction[0], res.residuals[0]))
        self.last = res
        return res.fit_model, d.simulate(res.fit_model, fitted)

    def race(self, starts, on: frozenset):
        """``(fitted, prediction, label)``: one model fitted on every sample from each of
        `starts` (``[(label, model)]``, `fitting._start.lag_starts`), `max_steps` each; the
        fit of the least training SSE (a non-finite one never wins) is kept and, where it
        stopped at its step limit, continued once (as the base-model options race,
        `fitting._select._kept`); `last` is its result. One start: one `fit`, label ``""``."""
        if len(starts) == 1:
            return (*self.fit(starts[0][1], on), "")
        ok = np.isfinite(self.data.F)

        def one(start):
            label, model = start
            self.log(f"  from the {label} ...")
            fitted, pred = self.fit(model, on)
            sse = float(np.sum((pred - self.data.F)[ok] ** 2))
            return sse if np.isfinite(sse) else np.inf, label, fitted, pred, self.last

        fits = self.map(one, starts)
        sse, label, fitted, pred, self.last = min(fits, key=lambda f: f[0])
        self.log(f"  kept the fit from the {label} (training RMSE "
                 f"{np.sqrt(sse / ok.sum()):.4g} N)")
        if not _converged(self.last):
            self.log(f"  continuing the fit from the {label} ...")
            fitted, pred = self.fit(fitted, on)
        return fitted, pred, label

    def fold_fit(self, model, on: frozenset, train=None):
        """`fit` on a fold's training samples (every sample without `train`), continued
        once from where it stopped when it did not converge: the step budget of every
        option's fit."""
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
        def one(k):
            train = folds[k][0]
            model = current.fold_models[k]
            resid = self.data.F - current.fold_preds[k]
            s = _signals(self.data, model.without_effects())
            for i, name in new.items():
                e = start_effect(name, self.data, None, resid, s, weights=train)
                model = eqx.tree_at(lambda m, i=i: m.effects[i], model, e)
            return *self.fold_fit(model, option.on, train), self.last

        for fit in self.map(one, range(len(folds))):
            option._fold(*fit)

    def reference(self, current: Option, folds) -> None:
        """Set `current.fold_refs`, what every option is judged against: per fold, the
        current model's fold fit, or where it stopped at its step limit, that fit continued
        with the budget each option gets from it (`fold_fit`). Equal effort: an option is
        not credited with the improvement a cut fit leaves, only with its own freedom."""
        if current.fold_refs:
            return
        def one(k):
            if current.fold_converged[k]:
                return current.fold_preds[k]
            self.log(f"  continuing the current model's fold {k} fit (stopped at its "
                     "step limit) as the reference ...")
            return self.fold_fit(current.fold_models[k], current.on, folds[k][0])[1]

        current.fold_refs.extend(self.map(one, range(len(folds))))

    def cross_validate(self, option: Option, folds, current: Option | None = None) -> None:
        """Refit `option` from its start (`option.model`) with each fold held out; a
        base-model option made from the current model (`Option.make`) from the one made
        from `current`'s fit on that fold's training samples (nested and paired, as
        `cross_validate_nested`). Not from its fit on all samples: a fit started at an
        optimum can stop at once (the solver's tolerance test), leaving the held-out
        blocks predicted by a model that was fitted on them."""
        if option.fold_preds:
            return
        def one(k):
            start = (_replaced(option.make, current.fold_models[k])
                     if option.make is not None and current is not None else option.model)
            return *self.fold_fit(start, option.on, folds[k][0]), self.last

        for fit in self.map(one, range(len(folds))):
            option._fold(*fit)


def default_workers() -> int:
    """How many fits a `Fitter` runs at once (`Fitter.map`): the environment variable
    ``JAXFRIC_WORKERS`` (a positive integer; 1 runs them one after another), else the
    cores this process may use."""
    given = os.environ.get("JAXFRIC_WORKERS", "").strip()
    if given:
        if not given.isdigit() or int(given) < 1:
            raise ValueError(f"JAXFRIC_WORKERS={given!r}: give a positive integer")
        return int(given)
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
        os.cpu_count() or 1)


def _replaced(make, model):
    """`model` (a fit with its effects) with its plain model replaced by `make`: a plain
    model, or a function of the fitted plain model that returns one (a richer model that
    starts where the fit is, `fitting._start.gms_like`)."""
    effects = tuple(getattr(model, "effects", ()))
    new = _params.to_fit_representation(
        make if isinstance(make, eqx.Module) else make(model.without_effects()))
    return new + effects if effects else new
