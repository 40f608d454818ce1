"""The diagnosis's decision: which effects to add, judged by full refits and blocked
cross-validation, with one rule (`fitting._rules.DiagnosisRules`).

**Options.** Every candidate effect of `jaxfric.effects` with a linear parameter is an
option, and so is another base model (`base_options`: a GMS with more elements, a
LuGre), which says "the base model is the limit here" when it wins. All effects sit in one
*superset* model (``plain + every candidate``, each switched off by its linear parameters
at 0, ``param(..., linear=True)``), so every refit fits the same compiled program; an option
switches its effect on by freeing its parameters (the free set is data, not structure).
Its Jacobian is computed over the free coordinates only (``fit_datasets(..., narrow=True)``:
slots of 8, one program per width; the same fit, without the held effects' columns).

**The base model** is fitted from its start and, with a friction lag, from a fast-lag
start (`fitting._start.lag_starts`), the better training fit kept (`Fitter.race`; not
again when `diagnose` raced them on every sample of a long record); its folds start from
the start kept.

**Each round** (forward selection):

1. each option is fitted jointly with the current model to convergence on every sample
   (`max_steps`, continued once where it stopped there, as every fold fit):
   its nonlinear parameters start at the grid point (`AbstractEffect.grid`) whose term
   best regresses the current residual, its linear ones at that regression's values, the
   rest of the model at the current fit; a base-model option from each of its own
   starts (`_replaced`; a GMS at the fit and read off the data), `max_steps` each, the
   best training fit standing for it (continued; one model, several starts: one option,
   one place among the `tried`) and, when it is cross-validated, every start is, the one
   of most held-out gain kept (`_kept`, `_held_out_race`), in later
   rounds from its own fit of the round before with the current model's effects at
   their fitted values (it starts where it ended, the effect just added included);
2. an option whose refit removes no more training SSE than ``2 q s^2`` (`_optimism`: what
   q added coordinates remove when they fit only noise) is not cross-validated, nor one
   that cannot qualify (not physical, or its fit not converged: `_admissible`); of the
   others, the `tried` with the lowest training error are: refitted with each fold held
   out in turn (`folds`, a plain list of ``(train_weights, test_weights)``;
   `time_block_folds` makes the default), each from the current model's own fit on that
   fold's training samples, its grid start picked again on those samples
   (`fitting._refits.Fitter.cross_validate_nested`); a base-model option, which does not
   contain the current model, is refitted from the start it was kept from, made from the
   current model's fit on that fold's training samples (`Fitter.cross_validate`);
3. an option qualifies when ``log(SSE_current / SSE_option)`` of the held-out samples,
   block by block (each contiguous run of a fold's test samples is a block), has a mean
   above `z` standard errors (`block_z`; the blocks of one fold counted as one piece of
   evidence where they move together, `standard_error`) and above
   ``log(1 / (1 - min_gain))`` by that much (`lower_gain`: significant and relevant,
   `DiagnosisRules.min_gain`), every fitted parameter is in
   its physical range (``param(..., physical=(lo, hi))``) and its fit on every sample
   ended by a rule of its own (`fitting._refits._converged`); of those that qualify, the
   one with the largest held-out gain is added, but where it is a base-model change, an
   effect the data do not tell apart from it (their difference under `z` standard
   errors, `_between`) comes first: a richer base model can stand in for any effect, so
   the effect is the more specific finding the data support as well. Between effects,
   the larger gain decides (a count of one or two coordinates says nothing of which is
   right: an offset that stands in for a joint's gravity load). Fold fits
   are compared at equal effort (`Fitter.reference`); one stopped at its step limit is
   judged where it stopped;
4. when none qualifies, the pairs of the options tested are refitted and judged the same.

The round repeats until nothing qualifies or `max_added` rounds added something.
"""

import dataclasses
import itertools
from collections.abc import Callable, Sequence

import equinox as eqx
import numpy as np

from . import _params
from ._candidates import _off, _signals, physical, start_effect, switchable
from ._fit import _finite
from ._folds import _blocks, run_folds, time_block_folds  # noqa: F401 (re-exported)
from ._refits import _replaced, Fitter, Option
from ._rules import DiagnosisRules
from ._start import lag_starts


def judge(option: Option, current: Option, folds, F: np.ndarray,
          z: float = DiagnosisRules.z) -> None:
    """Set `option`'s held-out gain over `current` (share of the current model's held-out
    SSE), ``z``: the mean block gain over its standard error, and ``lower``: the gain
    that mean less `z` standard errors stands for (`lower_gain`). The current model's
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
    option.lower = lower_gain(option.block_ref, option.block_gains, option.block_folds, z)


def _log_ratios(ref, gains) -> np.ndarray:
    ref = np.maximum(np.asarray(ref, float), np.finfo(float).tiny)
    new = np.maximum(ref - np.asarray(gains, float), np.finfo(float).tiny)
    return np.log(ref / new)


def block_z(ref, gains, folds) -> float:
    """The rule's statistic: the mean over blocks of ``log(SSE_current / SSE_option)``
    (held out, block by block), over its standard error (`standard_error`)."""
    r = _log_ratios(ref, gains)
    se = standard_error(r, np.asarray(folds))
    return float(r.mean() / se) if se > 0 else (np.inf if r.mean() > 0 else 0.0)


def lower_gain(ref, gains, folds, z: float) -> float:
    """The share of a typical block's held-out SSE (geometric mean over blocks) an option
    is shown to remove at `z` standard errors: ``1 - exp(-(mean - z se))`` of the block
    log ratios (`block_z`); the rule's relevance, compared with `DiagnosisRules.min_gain`.
    Minus infinity for one block."""
    r = _log_ratios(ref, gains)
    se = standard_error(r, np.asarray(folds))
    return float(-np.expm1(-(r.mean() - z * se))) if np.isfinite(se) else -np.inf


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
           base_options: Callable[[], list] = lambda: [], log=None,
           race: bool = True, max_added: int = 4) -> list[Round]:
    """Forward selection from model `start` (plain) over effect names `candidates` and the
    base models `base_options()` gives (``[(name, ((label, plain model or maker), ...))]``:
    each fitted from every start, the best held-out one kept, `_replaced`);
    see the module docstring. `race`: the base fit races its lag starts; False where the
    caller raced them already (on every sample of a long record) and `start` is the one
    kept. `max_added`: at most this many rounds add something (an effect, a pair or a base
    model). Returns the rounds; the last round's ``current`` is the final model."""
    log = log or (lambda *_: None)
    data = fitter.data
    names = [n for n in candidates if switchable(n)]
    plain = _params.to_fit_representation(start)
    slots = [_off(data.grid(n)[0]) for n in names]
    superset = plain + tuple(slots)
    log(f"fitting the base model ({len(names)} candidate effects held at 0) ...")
    # the kept fit's start is its folds' start too
    starts = lag_starts(superset, fitter.fixed) if race else [("given start", superset)]
    # the base-model options' programs compile while the base model is fitted
    ahead = fitter.compile_ahead([
        lambda s=s: (_replaced(_base_starts(s, None, plain)[0][2], superset), frozenset())
        for _, s in base_options()])
    fitted, pred, won = fitter.race(starts, frozenset())
    for thread in ahead:
        thread.join()
    current = Option(("base",), dict(starts).get(won, superset), frozenset(), fitted=fitted,
                     pred=pred, result=fitter.last, start=won,
                     sse=float(np.sum((pred - data.F) ** 2)))
    rounds, switched = [], False
    earlier = {}  # base-model option name -> (start, make, its plain fit of the round before)
    while len(rounds) < max_added:
        resid = data.F - current.pred
        signals = _signals(data, current.fitted.without_effects())
        options = []
        for i, n in enumerate(names):
            if i in current.on:
                continue
            eff = start_effect(n, data, None, resid, signals)
            model = eqx.tree_at(lambda m, i=i: m.effects[i], current.fitted, eff)
            options.append(Option((n,), model, current.on | {i}))
        groups = [] if switched else [
            [Option((bname,), _replaced(begin, current.fitted), current.on, base=True,
                    make=make, start=label)
             for label, make, begin in _base_starts(starts, earlier.get(bname),
                                                    current.fitted.without_effects())]
            for bname, starts in base_options()]
        # every fit of the round at once (`Fitter.map`), the slow base-model starts first
        fitter.map(lambda job, c=current: _refit(fitter, *job, c, log),
                   [(o, len(g) == 1) for g in groups for o in g] + [(o, True) for o in options])
        options += fitter.map(lambda g, c=current: _kept(fitter, g, c, log), groups)
        options.sort(key=lambda o: o.sse)
        _optimism(fitter, current, options)
        best = _admissible([o for o in options if o.sse < current.sse - o.optimism],
                           log)[:rules.tried]
        chosen = _cross_validate(fitter, current, best, folds, rules, log)
        if chosen is None and len(rounds) + 2 <= max_added:
            singles = [o for o in best if not o.base]
            pairs = [(_pair(a, b, current), min(a, b, key=lambda o: o.sse))
                     for a, b in itertools.combinations(singles, 2)]
            fitter.map(lambda p, c=current: _refit(fitter, p[0], True, c, log), pairs)
            for o, single in pairs:  # what its other effect adds to its better single
                _optimism(fitter, single, [o])
            options += [o for o, _ in pairs]
            chosen = _cross_validate(fitter, current, _admissible(
                [o for o, _ in pairs if o.sse < o.against - o.optimism], log), folds, rules,
                log)
        rounds.append(Round(options, chosen, current))
        if chosen is None:
            break
        earlier = {o.name: (o.start, o.make, o.fitted.without_effects()) for o in options
                   if o.base and o.fitted is not None and _finite(o.fitted)}
        switched |= chosen.base
        current = chosen
    return rounds


def _base_starts(starts, earlier, plain) -> list[tuple]:
    """``(label, make, start)`` of each start of one base-model option this round: each
    of `starts` (``(label, plain model or maker)``) made from the fitted plain model
    `plain`, a start that is another's (a GMS from the fit falls back to the one read off
    the data) once; in a later round the option's own fit of the round before
    (`earlier`: ``(label, make, plain fit)``), one start."""
    if earlier is not None:
        return [earlier]
    out = []
    for label, make in starts:
        start = make if isinstance(make, eqx.Module) else make(plain)
        if not any(start is s for _, _, s in out):
            out.append((label, make, start))
    return out


def _refit(fitter: Fitter, o: Option, continued: bool, current: Option, log) -> None:
    """Fit option `o` on every sample with the budget of a fold fit (`Fitter.fold_fit`:
    continued once where it stopped at its step limit; not `continued`: one fit, for a
    start that competes with others, `_kept`); set its fit, training SSE and physical
    check."""
    log(f"  refitting with {o.name}{f' ({o.start})' if o.start else ''} ...")
    o.fitted, o.pred = (fitter.fold_fit if continued else fitter.fit)(o.model, o.on)
    _set(fitter, o, current)


def _set(fitter: Fitter, o: Option, current: Option) -> None:
    o.result = fitter.last
    o._note("fit on every sample", o.result)
    o.sse = float(np.sum((o.pred - fitter.data.F) ** 2))
    o.physical = "" if o.base else "; ".join(
        p for i in sorted(o.on - current.on) if (p := physical(o.fitted.effects[i], fitter.data)))


def _kept(fitter: Fitter, group: list[Option], current: Option, log) -> Option:
    """One option fitted from several starts (`group`, each fitted by `_refit`, with
    `max_steps` where there are several): the best training fit stands for the option
    among the `tried` and is continued where it stopped; the others are its `rivals`,
    cross-validated with it (`_held_out_race`)."""
    kept = min(group, key=lambda o: o.sse if np.isfinite(o.sse) else np.inf)
    if len(group) > 1:  # a single start was continued by `_refit` already
        _continue(fitter, kept, current, log)
    kept.rivals = [o for o in group if o is not kept and np.isfinite(o.sse)]
    return kept


def _continue(fitter: Fitter, o: Option, current: Option, log) -> None:
    """Continue `o`'s fit on every sample once where it stopped at its step limit."""
    if o.unconverged:
        log(f"  continuing {o.name} ({o.start}) ...")
        o.unconverged = ""
        o.fitted, o.pred = fitter.fit(o.fitted, o.on)
        _set(fitter, o, current)


def _held_out_race(fitter: Fitter, o: Option, current: Option, folds, z: float,
                   log) -> None:
    """Of base-model option `o` and its `rivals` (its other starts), keep in `o` the one
    whose cross-validation removes the most held-out SSE: a start is chosen by the rule's
    measure, not by its training fit (a slow friction lag that remembers the motion fits
    the training samples far better and predicts held-out blocks no better)."""
    for r in o.rivals:
        r.optimism, r.against = o.optimism, o.against
        fitter.cross_validate(r, folds, current)
        judge(r, current, folds, fitter.data.F, z)
        log(f"    from the {r.start}: held-out SSE {-100 * r.gain:+.3g} %, z = {r.z:.2f}")
    best = max([o, *o.rivals], key=lambda r: r.gain if np.isfinite(r.gain) else -np.inf)
    if best is not o:  # swapped: `o` stays where lists hold it, the kept start a rival
        for f in dataclasses.fields(Option):
            a, b = getattr(o, f.name), getattr(best, f.name)
            setattr(o, f.name, b)
            setattr(best, f.name, a)
        o.rivals, best.rivals = best.rivals, []
        log(f"    kept the fit from the {o.start}")
        _continue(fitter, o, current, log)


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


def _admissible(options: list[Option], log) -> list[Option]:
    """The `options` that can qualify: an option whose fit on every sample is not physical
    or did not converge cannot, whatever its held-out error (both are known before any
    fold is fitted). The others are marked (`Option.skipped` says why) and are not
    cross-validated, so they take none of the `tried` places."""
    out = []
    for o in options:
        o.skipped = "; ".join(w for w in (o.physical and f"not physical: {o.physical}",
                                          o.unconverged and f"not converged: {o.unconverged}")
                              if w)
        if o.skipped:
            log(f"  {o.name}: not cross-validated, it cannot qualify ({o.skipped})")
        else:
            out.append(o)
    return out


def _cross_validate(fitter, current, options, folds, rules, log):
    """Cross-validate `current` and `options` (`_admissible` ones); the qualifying one of
    largest held-out gain."""
    fitter.cross_validate(current, folds)
    fitter.reference(current, folds)
    for o in options:
        log(f"  cross-validating {o.name} ({len(folds)} folds) ...")
        names = {i: type(o.model.effects[i]).name for i in o.on - current.on}
        if names and not o.base:
            fitter.cross_validate_nested(o, current, folds, names)
        else:
            fitter.cross_validate(o, folds, current)
        judge(o, current, folds, fitter.data.F, rules.z)
        log(f"    held-out SSE {-100 * o.gain:+.3g} % (of a typical block at most "
            f"{-100 * o.lower:+.3g} %), z = {o.z:.2f}"
            + (f" (judged where stopped: {o.cut})" if o.cut else ""))
        if o.rivals:
            _held_out_race(fitter, o, current, folds, rules.z, log)
    # physical and converged: `_admissible` kept only those, checked again for a caller
    # that did not
    good = [o for o in options if o.z >= rules.z and o.lower >= rules.min_gain
            and not o.physical and not o.unconverged]
    if not good:
        return None
    best = max(good, key=lambda o: o.gain)
    # of those the data do not tell apart from the best, an effect before a base change
    alike = [o for o in good if o is best or _between(best, o) < rules.z]
    chosen = max(alike, key=lambda o: (not o.base, o.gain))
    chosen.ties = [(o.name, z) for o in good if o is not chosen
                   and (z := _between(chosen, o)) < rules.z]
    return chosen


def _between(a: Option, b: Option) -> float:
    """How much better `a` predicts the held-out blocks than `b` (both judged against the
    same current model): the mean block ``log(SSE_b / SSE_a)`` over its standard error.
    Under `z`, the data do not tell the two apart (a look-alike: an offset and a
    direction-dependent level on a record that slides at equal speeds both ways)."""
    r = _log_ratios(a.block_ref, a.block_gains) - _log_ratios(b.block_ref, b.block_gains)
    se = standard_error(r, np.asarray(a.block_folds))
    return float(r.mean() / se) if se > 0 else (np.inf if r.mean() > 0 else 0.0)
