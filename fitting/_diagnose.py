"""Diagnosis: where a fitted model fails, which physical effect is missing, and the error
falling as effects are added.

**Ranking effects** (`diagnose`). The velocity is estimated from the position with a
zero-phase difference (`derivatives`, `fitting._derivatives`) unless given. The data are cut
into `blocks` contiguous time blocks; every third block is held out, the rest is the
training set (interleaved, so that a slow drift or a position dependence is seen in both).
The model is fitted on the training set (restarted while that still helps, see
`fitting._diagnose_context._step`).
Then, for every candidate effect of `jaxfric.effects`:

1. its nonlinear parameters (cogging period, Stribeck velocity, presliding stiffness, lag
   time constant) are searched on a grid, and for each grid point the residual of the
   training set is regressed, by linear least squares, on the effect's columns *together
   with* the Jacobian columns of the model's own parameters: one Gauss-Newton step of the
   joint fit from the baseline optimum, so an effect only scores for what the model's own
   parameters cannot absorb;
2. the **score** is the fraction of the held-out residual sum of squares that this step
   removes beyond the same step without the effect (a flexible term that only fits noise
   removes nothing from held-out data);
3. it is **significant** when the score is at least `min_score` and the held-out gain is
   consistent where the effect acts (`fitting._evidence`): on the held-out samples where
   the effect changes the residual, the per-sample gain in squared residual, in batches
   longer than its autocorrelation, has a batch-means ``t`` of at least `min_t`. An
   effect confined to one regime (a drag at high speed, friction in one direction) is
   judged where it acts, not diluted by the samples it leaves alone; a term that fits
   smooth model mismatch gets long batches, few of them, and a small ``t``. With two
   effects missing, each one's screen sees the other as noise; so the leading candidates
   (score at least `min_score`, at most three) are also regressed together, and one whose
   contribution is consistent in that joint step is significant too.

The best significant effect is added (``model + effect``, starting from the regression's
values; significant effects within 10 % of the best score are each refitted, and a
significantly lower held-out error decides, else the higher score), everything
is refitted jointly on the training set (twice: from the fitted model, and from the
starting model with the effects, which is not bent by the missing effect; the better
training fit is kept, and a fit that stops at its step limit is restarted while that still
lowers its error by more than 1 %, up to five times; a drift's settling time held to the
range the screen searched, `_refit_props`),
and the ranking repeats on the new residual until nothing significant is left. The
held-out RMSE after each addition is reported; an addition whose refit removes less than
``min_score/2`` of the held-out SSE is undone and marked not significant, and the next
significant candidate is tried. When nothing is significant but the best score is at least
``4*min_score`` (a large effect whose screen a second missing effect made inconsistent),
that candidate is tried too, and kept only if the refit's held-out improvement is
consistent where it acts (``t`` at least `min_t`). A refit whose held-out gain is clear (at
least ``2*min_score``, `fitting._folds.needs_folds`) but not consistent on the one split, as
for an effect that acts in a regime the motion visits a few times, is refitted with each of the
other two folds of blocks held out in turn (`fitting._folds`); it is added when it removes
at least `min_score` of the SSE of all folds and that evidence passes the same rule, or
its gain replicates where its term is large, in each fold. When nothing holds up, alone
or in pairs (below), the leading candidates (of the three best scores, those of at least
``2*min_score``) are refitted too, and the refit alone decides (`_try_leaders`: the
linearised screen sees only part of what a refit removes). A candidate tried and not
added says why in its evidence.

After the last step the baseline and final models are checked for plausibility
(`fitting._plausibility`: presliding range against the strokes, lag time against their
duration, prediction against the model's own steady state); the warnings are in
`Diagnosis.warnings`, the summary and the JSON.

When no single effect holds up, two missing effects may each be hiding the other (each
one's screen fits the other's residual with the wrong term). Every pair of candidates is
then regressed together in the same linearised step; the best pairs (at most `_PAIRS`)
that remove at least ``4*min_score`` of the held-out SSE, and ``min_score`` more than the
best single effect, are each added together and refitted, with the same checks; of those
that hold up, the one with the lower held-out error is kept, as one step. Each of the two
is then ranked by its share within the pair (the held-out SSE it removes when added to the
other), and the evidence says so.

**Long records.** A record of at least twice `search_samples` samples is ranked and tried
on a search copy of about that many (`fitting._search_copy`: one sample in k, the force
averaged over a centred window); the baseline and every step are then refitted on all
samples from where the search left them, so every error and parameter reported is of the
whole record, and the rankings and trials are of the copy (`Diagnosis.search` says so).
The fits, restarts and context every step shares are in `fitting._diagnose_context`.

"""

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from ._candidates import _code, Candidate
from ._diagnose_context import _contained, _Context, _context, effect_names, Step
from ._evidence import convincing, evidence, needs, STRONG_SHARE
from ._folds import needs_folds, on_all_folds, on_folds
from ._plausibility import plausibility
from ._result import saved_model
from ._screen import _base_jacobian, _joint_check, _pair_screen, _screen
from ._search_copy import at_full_rate, describe as describe_search, search_context, SEARCH_SAMPLES


@dataclasses.dataclass
class Diagnosis:
    """Outcome of `diagnose`: `baseline` and `steps` (one `Step` per added effect),
    `rankings` (the candidate list before each step; `rankings[0]` on the baseline), the
    held-out mask, and the final model."""

    baseline: Step
    steps: list[Step]
    rankings: list[list[Candidate]]
    holdout: np.ndarray
    model: object
    model_name: str
    velocity: str = ""  # how the velocity was obtained (`fitting._derivatives.describe`)
    #: The velocity estimate as options (``{"method": ..., "window_s": ...}``; None for a
    #: given velocity), so that `jaxfric simulate --params` can use the same.
    derivatives: dict | None = None
    #: Implausible features of the baseline and of the final model (`fitting._plausibility`).
    warnings: dict = dataclasses.field(default_factory=dict)
    #: The deadband (m or rad) the positions were played through before the diagnosis
    #: (`jaxfric.motion.play`; the command line's ``--deadband``), or None.
    deadband: float | None = None
    #: Every joint refit tried, in order: ``{"round", "effects", "rmse_holdout_before",
    #: "rmse_holdout_after", "removed" (share of the held-out SSE), "t", "batches",
    #: "added", "tried_as" (why: `TRIED_AS`), "start" (the refit kept: from the "fitted
    #: model" or the "starting model" with the effects)}`` (``t`` None when infinite;
    #: ``"folds"`` when all three folds were asked, `fitting._folds`).
    trials: list[dict] = dataclasses.field(default_factory=list)
    #: For a long record, how the effects were searched on fewer samples
    #: (`fitting._search_copy`); empty when every sample was used throughout.
    search: str = ""
    #: What the diagnosis found beyond the effects, in words: "the base model is the limit
    #: here: ..." when a richer base model won (`fitting._diagnose_cv`); empty otherwise.
    finding: str = ""

    @property
    def candidates(self) -> list[Candidate]:
        return self.rankings[0]

    @property
    def final(self) -> Step:
        return self.steps[-1] if self.steps else self.baseline

    def to_json(self) -> dict:
        return {
            "baseline": {"model": self.model_name, "rmse": self.baseline.rmse,
                         "rmse_holdout": self.baseline.rmse_holdout,
                         "rel_error": self.baseline.rel_error,
                         "regimes": self.baseline.regimes},
            "candidates": [c.to_json() for c in self.candidates],
            "after": {"added": self.final.added, "rmse": self.final.rmse,
                      "rmse_holdout": self.final.rmse_holdout,
                      "rel_error": self.final.rel_error,
                      "regimes": self.final.regimes,
                      "steps": [{"added": s.added, "rmse": s.rmse,
                                 "rmse_holdout": s.rmse_holdout} for s in self.steps]},
            "velocity": self.velocity,
            "derivatives": self.derivatives,
            "warnings": self.warnings,
            "trials": self.trials,
            **({"search": self.search} if self.search else {}),
            **({"finding": self.finding} if self.finding else {}),
            **({} if self.deadband is None else {"deadband": self.deadband}),
            "fitted_model": saved_model(self.model),
        }

    def summary(self) -> str:
        lines = [f"baseline {self.model_name}: RMSE {self.baseline.rmse:.4g} N "
                 f"(held out {self.baseline.rmse_holdout:.4g} N, "
                 f"{100 * self.baseline.rel_error:.3g} % of the RMS force)"]
        if self.velocity:
            lines.append(f"velocity: {self.velocity}")
        if self.search:
            lines.append(f"search: {self.search}")
        lines.append("candidate effects:")
        for c in self.candidates:
            mark = "*" if c.significant else " "
            lines.append(f" {mark} {c.name:<20} score {c.score:7.3f}  t {c.t_stat:6.1f}  "
                         f"{c.evidence}")
        for before, s in zip([self.baseline, *self.steps], self.steps):
            new = " + ".join(s.added[len(before.added):])
            lines.append(f"+ {new:<20} RMSE {s.rmse:.4g} N (held out "
                         f"{s.rmse_holdout:.4g} N, {100 * s.rel_error:.3g} %)")
        if not self.steps:
            lines.append("nothing significant to add")
        if self.finding:
            lines.append(self.finding)
        for which, flags in self.warnings.items():
            lines += [f"warning ({which} model): {flag}" for flag in flags]
        return "\n".join(lines)


#: Most pairs of effects tried together when no single effect holds up (see `diagnose`).
_PAIRS = 2

#: Why a refit was tried, as its trial record says (``"tried_as"``): a candidate
#: significant on the screen, the largest score although not consistent
#: (`_try_singles`), a pair (`_try_pairs`), a leading candidate (`_try_leaders`).
TRIED_AS = ("significant", "largest score", "pair", "leading")


@dataclasses.dataclass
class _State:
    """Where a diagnosis stands: the current model, its residual (on all samples), its
    held-out RMSE and the effects added so far."""

    current: object
    resid: np.ndarray
    best_holdout: float
    added: list[str]
    #: Every refit tried (`_refit`): effects, held-out RMSE before and after, share of the
    #: held-out SSE removed, consistency, and whether it was added.
    trials: list[dict] = dataclasses.field(default_factory=list)
    #: The current model's residual with each fold held out in turn (`fitting._folds`),
    #: once a round needs it; None until then and after each step.
    fold_resid: np.ndarray | None = None


def _rank(ctx: _Context, state: _State, names, J) -> list[Candidate]:
    """Every candidate not yet added, screened on the current residual, best first, with
    the leading ones re-tested together (`_joint_check`)."""
    ranking = []
    for name in names:
        if name in state.added:
            continue
        c = _screen(name, state.current, ctx.t, ctx.x, ctx.v_arr, ctx.F, state.resid, J,
                    ctx.train, ctx.test, ctx.min_score, ctx.min_t, load=ctx.load,
                    a=ctx.a)
        if c is not None:
            ranking.append(c)
    ranking.sort(key=lambda c: c.score, reverse=True)
    _joint_check(ranking, state.current, ctx.t, ctx.x, ctx.v_arr, state.resid, J, ctx.train,
                 ctx.test, ctx.min_score, ctx.min_t, load=ctx.load, a=ctx.a)
    for c in ranking[:3]:
        ctx.log(f"  {c.name}: score {c.score:.3f}, t {c.t_stat:.1f}"
                + ("  (significant)" if c.significant else ""))
    return ranking


def _refit(ctx: _Context, state: _State, new_effects, names_new, why: str):
    """Add `new_effects`, refit (from the fitted model and from the starting model with
    the effects; the better training fit is kept). Returns the step, its residual, whether
    it removed enough held-out SSE, and its consistency (t, batches). The trial's record
    says `why` it was tried (`TRIED_AS`) and which start was kept."""
    trial, trial_resid = ctx.step(state.current + new_effects, [*state.added, *names_new],
                                  restart=True)
    # The fitted model can sit where it compensated for the missing effect (a distorted
    # Stribeck curve, say), a poor start for the refit: also refit from the starting model
    # with the effects, and keep the better training fit.
    effects = tuple(getattr(state.current, "effects", ()))
    plain = ctx.model.without_effects()
    fresh, fresh_resid = ctx.step(plain + (*effects, *new_effects),
                                  [*state.added, *names_new], restart=True)
    start = "fitted model"
    if float(fresh.fit.rmse) < float(trial.fit.rmse):
        trial, trial_resid, start = fresh, fresh_resid, "starting model"
    # The refit must remove at least half the screening threshold of held-out SSE, and an
    # effect not yet shown consistent must now be so where it acts.
    enough = trial.rmse_holdout**2 < (1.0 - 0.5 * ctx.min_score) * state.best_holdout**2
    ev = evidence(state.resid, trial_resid, ctx.test, ctx.v_arr)
    removed = 1.0 - trial.rmse_holdout**2 / state.best_holdout**2
    state.trials.append({"round": len(state.added), "effects": list(names_new),
                         "rmse_holdout_before": state.best_holdout,
                         "rmse_holdout_after": trial.rmse_holdout, "removed": removed,
                         "t": ev.t if np.isfinite(ev.t) else None,
                         "batches": ev.batches, "added": False, "tried_as": why,
                         "start": start})
    return trial, trial_resid, enough, ev.t, ev.batches, removed


def _holds_up(ctx: _Context, state: _State, chosen: Candidate, why: str = "significant"):
    """Add `chosen` alone and refit: ``(step, residual)`` when the refit holds up (removes
    enough held-out SSE, and its gain is convincing where it acts, `convincing`, or, for a
    candidate significant on the screen, removes at least `STRONG_SHARE`), else ``None``
    with the reason in its evidence. `why`: see `TRIED_AS`."""
    ctx.log(f"adding {chosen.name} and refitting ...")
    trial, trial_resid, enough, t_refit, n_blocks, removed = _refit(
        ctx, state, (chosen.effect,), [chosen.name], why)
    # The refit is the model itself: its held-out gain must be convincing (a linearised
    # screen can pass on the model's mismatch alone), or, for a candidate whose screen was
    # consistent, at least large (a slow drift has too few batches for any t).
    held = enough and (convincing(removed, t_refit, ctx.min_t)
                       or (chosen.significant and removed >= STRONG_SHARE))
    folds = _folds(ctx, state, trial, trial_resid, [chosen.name],
                   enough and not held and needs_folds(removed, ctx.min_score))
    if held or (folds is not None and folds.holds(ctx.min_t, ctx.min_score)):
        if not chosen.significant:
            chosen.significant, chosen.t_stat = True, t_refit
        if folds is None:
            chosen.evidence += (f"; confirmed by the joint refit: it removed "
                                f"{100 * removed:.3g} % of the held-out SSE, consistent over "
                                f"{n_blocks} held-out batches (t = {t_refit:.1f})")
        else:
            chosen.t_stat = folds.t
            chosen.evidence += (f"; confirmed by the joint refit: it removed "
                                f"{100 * removed:.3g} % of the held-out SSE (t = "
                                f"{t_refit:.1f} over {n_blocks} batches: few episodes), and "
                                f"{folds.words()}")
        return trial, trial_resid
    why = (f"the joint refit removed {100 * removed:.3g} % of the held-out SSE (needs "
           f"{50 * ctx.min_score:.3g} %)" if not enough else
           f"its gain in the joint refit was not consistent (t = {t_refit:.1f}, "
           f"{needs(ctx.min_t)}; it removed {100 * removed:.3g} %)")
    if folds is not None:
        why += f", nor {folds.words()}"
    ctx.log(f"  {chosen.name} not added: {why}")
    chosen.evidence += f"; not added: {why}"
    chosen.significant = False
    return None


def _folds(ctx: _Context, state: _State, trial, trial_resid, names_new, needed: bool):
    """When `needed` (a large held-out gain, inconsistent on the one split), the evidence of
    all three held-out folds (`fitting._folds`), also kept in the last trial's record;
    else None."""
    if not needed:
        return None
    ctx.log("  a large gain on few held-out episodes: refitting with each of the other "
            "two folds held out ...")
    if state.fold_resid is None:  # the same for every candidate of this round
        state.fold_resid = on_folds(ctx, state.current, list(state.added), state.resid)
    folds = on_all_folds(ctx, state.current, list(state.added), trial.fit.model,
                         [*state.added, *names_new], state.resid, trial_resid,
                         ref=state.fold_resid)
    ctx.log(f"  {folds.words()}")
    state.trials[-1]["folds"] = {"removed": folds.removed, "batches": folds.batches,
                                 "t": folds.t if np.isfinite(folds.t) else None,
                                 "shares_where_it_acts": list(folds.shares),
                                 "where": folds.where}
    return folds


def _closest_call(ctx: _Context, held):
    """Of candidates whose refits all held up (of nearly equal score, `_try_singles`, or
    leading candidates refitted when nothing else held up, `_try_leaders`), the one to add,
    and why in words. The lower held-out error decides when it is significantly lower where
    the two refits differ (`fitting._evidence`, ``t`` at least `min_t`); otherwise the
    data cannot tell them apart, and the screen's ranking stands: the higher score (the
    share of the held-out residual the effect explains beyond the model's own parameters),
    which named the hidden effect more often on the diagnosis bench than the screen's ``t``
    or the held-out error alone."""
    if len(held) == 1:
        return held[0][0], "held up where it did not"
    ranked = sorted(held, key=lambda h: h[1][0].rmse_holdout)
    (best, (step, resid)), (_, (other, other_resid)) = ranked[0], ranked[1]
    ev = evidence(other_resid, resid, ctx.test, ctx.v_arr)
    if ev.t >= ctx.min_t:
        return best, (f"fits the held-out data better (held-out RMSE {step.rmse_holdout:.4g} "
                      f"N against {other.rmse_holdout:.4g} N, t = {ev.t:.1f})")
    chosen, (step, _) = max(held, key=lambda h: h[0].score)
    return chosen, (f"fits the held-out data as well (held-out RMSE "
                    f"{step.rmse_holdout:.4g} N, the difference not "
                    f"significant: t = {ev.t:.1f}) and explains more of the residual "
                    f"(score {chosen.score:.3g})")


def _try_singles(ctx: _Context, state: _State, ranking):
    """Add the first significant candidate whose refit holds up: ``(accepted, step,
    residual)``, or ``(None, None, None)``. Significant candidates whose scores are within
    10 % of the best (an offset and an asymmetry during sliding explain almost the same
    share) are all refitted, and `_closest_call` picks one of those that hold up."""
    tries = [c for c in ranking if c.significant]
    close = [c for c in tries if c.score >= 0.9 * tries[0].score][:3] if tries else []
    if ranking and not ranking[0].significant and ranking[0].score >= 4 * ctx.min_score:
        # The largest score, but not consistent: often a second missing effect
        # confounding the linear screen. Try it first; the refit must confirm it where it
        # acts.
        out = _holds_up(ctx, state, ranking[0], "largest score")
        if out is not None:
            return [ranking[0]], *out
    if len(close) > 1:
        held = [(c, out) for c in close if (out := _holds_up(ctx, state, c)) is not None]
        if held:
            chosen, best = _closest_call(ctx, held)
            for c, _ in held:
                if c is not chosen:
                    c.evidence += (f"; not added: {chosen.name}, of nearly the same score, "
                                   f"{best}")
            return [chosen], *next(out for c, out in held if c is chosen)
    for chosen in tries[len(close) if len(close) > 1 else 0:]:
        out = _holds_up(ctx, state, chosen)
        if out is not None:
            return [chosen], *out
    return None, None, None


#: At most this many leading candidates are refitted when the screen finds nothing
#: (`_try_leaders`), as the screen's joint check regresses at most three together.
_LEADERS = 3


def _leaders(ctx: _Context, state: _State, ranking) -> list[Candidate]:
    """The candidates `_try_leaders` refits: of the `_LEADERS` best scores, those of at least
    ``2*min_score`` not refitted alone yet this round."""
    tried = {tuple(tr["effects"]) for tr in state.trials if tr["round"] == len(state.added)}
    return [c for c in ranking[:_LEADERS]
            if c.score >= 2 * ctx.min_score and (c.name,) not in tried]


def _try_leaders(ctx: _Context, state: _State, ranking):
    """Nothing held up, alone or in pairs: refit the leading candidates (`_leaders`) and let
    the refit decide. The screen is one linearised step from the fitted model, which has
    bent its own parameters toward the missing effect; it can see only part of what a refit
    removes (on the diagnosis bench's LuGre truth at 10 ms, a mass error scores 15 % on the
    screen, t = 2.2, and its refit removes 36 % of the held-out SSE, t = 4.2). A leader is
    added only when its refit holds up by the rules of `_holds_up` for a candidate that is
    not significant: its own held-out gain convincing where it acts, or confirmed on all
    three folds; of several that hold up, `_closest_call` picks one. ``(accepted, step,
    residual)`` or ``(None, None, None)``."""
    leaders = _leaders(ctx, state, ranking)
    if not leaders:
        return None, None, None
    ctx.log("nothing significant held up; refitting the leading candidates "
            f"({', '.join(c.name for c in leaders)}) ...")
    held = []
    for c in leaders:
        c.evidence += "; refitted as a leading candidate (the screen found nothing that held up)"
        out = _holds_up(ctx, state, c, "leading")
        if out is not None:
            held.append((c, out))
    if not held:
        return None, None, None
    chosen, best = _closest_call(ctx, held)
    for c, _ in held:
        if c is not chosen:
            c.evidence += f"; not added: {chosen.name}, also a leading candidate, {best}"
    return [chosen], *next(out for c, out in held if c is chosen)


def _mark_added(trials: list[dict], names: set[str]) -> None:
    """Mark the last refit of exactly `names` as the one added."""
    for trial in reversed(trials):
        if set(trial["effects"]) == names:
            trial["added"] = True
            return


def _describe_pair(pair, t_refit: float, n_blocks: int) -> None:
    """Each candidate of an accepted pair takes the pair's values, its share within the
    pair as its score, and evidence saying so."""
    alone = [(c.score, c.t_stat) for c in pair.candidates]
    for c, share, (score, t_stat), (other_score, _), other, effect in zip(
            pair.candidates, pair.shares, alone, alone[::-1], pair.candidates[::-1],
            pair.effects):
        c.evidence = (
            f"{effect.describe()}; found together with {other.name}: both explain "
            f"{100 * pair.score:.3g} % of the held-out residual variance, {other.name} alone "
            f"{100 * other_score:.3g} %, so adding {c.name} to it removes {100 * share:.3g} % "
            f"(alone {100 * score:.3g} %, t = {t_stat:.1f}); confirmed by the joint refit of "
            f"both, consistent over {n_blocks} held-out batches (t = {t_refit:.1f})")
        c.effect, c.code = effect, _code(effect)
        c.score, c.significant, c.t_stat = float(share), True, t_refit


def _try_pairs(ctx: _Context, state: _State, ranking, J):
    """No single effect holds up: two effects can each be hidden by the other. Try the best
    pairs that explain clearly more together than any one alone; keep the one with the
    lower held-out error. ``(accepted, step, residual)`` or ``(None, None, None)``."""
    best_single = max((c.score for c in ranking), default=0.0)
    pairs = [p for p in _pair_screen(ranking, state.current, ctx.t, ctx.x, ctx.v_arr,
                                     state.resid, J, ctx.train, ctx.test,
                                     load=ctx.load, a=ctx.a)[:_PAIRS]
             if p.score >= 4 * ctx.min_score and p.score >= best_single + ctx.min_score]
    tried = []
    for pair in pairs:
        names_pair = [c.name for c in pair.candidates]
        ctx.log(f"adding {' and '.join(names_pair)} together (they explain "
                f"{100 * pair.score:.3g} % of the held-out residual jointly) and refitting ...")
        out = _refit(ctx, state, pair.effects, names_pair, "pair")
        ctx.log(f"  held-out RMSE {out[0].rmse_holdout:.4g} N (was {state.best_holdout:.4g} "
                f"N), consistency where they act t = {out[3]:.1f}")
        held = out[2] and convincing(out[5], out[3], ctx.min_t)
        folds = _folds(ctx, state, out[0], out[1], names_pair,
                       out[2] and not held and needs_folds(out[5], ctx.min_score))
        if held or (folds is not None and folds.holds(ctx.min_t, ctx.min_score)):
            if folds is not None:  # the evidence of all three folds
                out = (*out[:3], folds.t, folds.batches, out[5])
            tried.append((out, pair))
    if not tried:
        return None, None, None
    # Of the pairs that hold up (two effects with partly alike terms can compete, e.g. an
    # offset and an asymmetry), keep the lower held-out error.
    (trial, trial_resid, _, t_refit, n_blocks, _), pair = min(
        tried, key=lambda o: o[0][0].rmse_holdout)
    _describe_pair(pair, t_refit, n_blocks)
    ranking.sort(key=lambda c: c.score, reverse=True)
    accepted = sorted(pair.candidates, key=lambda c: c.score, reverse=True)
    trial.added = [*state.added, *(c.name for c in accepted)]
    return accepted, trial, trial_resid


def diagnose(
    model,
    t,
    x,
    F,
    v=None,
    *,
    effects: Sequence[str] | None = None,
    blocks: int = 24,
    min_score: float = 0.05,
    min_t: float = 3.0,
    max_added: int = 4,
    max_steps: int = 300,
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
    """Fit `model` to ``(t, x, F[, v])`` (SI), rank the missing effects, add the significant
    ones one at a time with a joint refit after each (see the module docstring).

    `effects`: names from `jaxfric.effects.EFFECTS` to consider (default all not already in
    the model, nor already one of its free parameters: ``viscous`` only when ``sigma2`` is
    held with `fixed`, see `_contained`; the effects of an angle,
    `jaxfric.effects.ROTARY_EFFECTS`, only when `rotary`: `x` is then an angle in rad).
    `fixed`: parameter names of `model` held at their values in every fit (e.g.
    ``("sigma2",)`` with ``sigma2 = 0`` for a model without viscous friction); the screening
    then does not let them absorb an effect either. `max_steps`: per fit. `load`: the
    transmitted load (N, or N m on a rotary axis; a file's ``load`` column): every fit and
    screen gets it, and the load-dependent effects (`jaxfric.effects.LOAD_EFFECTS`) are
    screened only when it is given. `derivatives`: how the velocity is estimated from the
    position when `v` is not given (``"central"``, ``"savgol"`` or ``"backward"``, over
    `velocity_window` seconds; see `fitting._derivatives`): every fit and screen uses that
    velocity, and the acceleration `jaxfric.effects.Inertia` reads by the same method (the
    central difference of the velocity, the Savitzky-Golay second derivative, or for
    ``"backward"`` the model's own backward difference), unless `a` (m/s^2, a measured
    column) is given. Data made by `jaxfric.simulate` without a velocity want
    ``"backward"``; measurements want a zero-phase estimate (the default).
    `search_samples`: a record of at least twice as many samples is searched on about
    this many (`fitting._search_copy`: the force averaged over windows), and the baseline
    and each step refitted on all samples; None or 0 searches on every sample.
    Returns a `Diagnosis`; its models are in the fit representation
    (`fitting.to_fit_representation`: a `PaperShape` appears as the equivalent
    `NormalizedPaperShape`, finite where the paper's ``a`` would overflow).
    """
    full = _context(model, t, x, F, v, blocks=blocks, max_steps=max_steps, fixed=fixed,
                    min_score=min_score, min_t=min_t, log=log, derivatives=derivatives,
                    velocity_window=velocity_window, load=load, a=a)
    ctx = search_context(full, search_samples)
    search = describe_search(full, ctx)
    if search:
        ctx.log(f"a long record: {search}")
    present = {e.name for e in getattr(ctx.model, "effects", ())}
    names = effect_names(effects, present | _contained(ctx.model, ctx.fixed) if not effects
                         else present, rotary, load is not None)
    ctx.log(f"fitting the baseline model on {int(ctx.train.sum())} of {ctx.t.size} samples "
            f"({int(ctx.test.sum())} held out in {blocks // 3} blocks) ...")
    baseline, resid = ctx.step(ctx.model, [], restart=True)
    state = _State(current=baseline.fit.model, resid=resid,
                   best_holdout=baseline.rmse_holdout, added=[])
    steps, rankings = [], []
    while True:
        J = _base_jacobian(state.current, ctx.t, ctx.x, ctx.v, ctx.fixed, load=ctx.load,
                           a=ctx.a)
        ranking = _rank(ctx, state, names, J)
        rankings.append(ranking)
        if len(state.added) >= max_added:
            break
        accepted, trial, trial_resid = _try_singles(ctx, state, ranking)
        if accepted is None and len(state.added) + 2 <= max_added:
            accepted, trial, trial_resid = _try_pairs(ctx, state, ranking, J)
        if accepted is None:
            accepted, trial, trial_resid = _try_leaders(ctx, state, ranking)
        if accepted is None:
            break
        steps.append(trial)
        _mark_added(state.trials, {c.name for c in accepted})
        state.added.extend(c.name for c in accepted)
        state.current, state.resid = trial.fit.model, trial_resid
        state.best_holdout, state.fold_resid = trial.rmse_holdout, None
    baseline, steps = at_full_rate(full, ctx, baseline, steps)
    final = (steps[-1] if steps else baseline).fit.model
    warnings = {"baseline": plausibility(baseline.fit.model, full.t, full.x, full.v, full.F,
                                         a=full.a, load=full.load)}
    if steps:
        warnings["final"] = plausibility(final, full.t, full.x, full.v, full.F, a=full.a,
                                         load=full.load)
    return Diagnosis(baseline=baseline, steps=steps, rankings=rankings, holdout=full.test,
                     model=final, model_name=model_name or type(ctx.model).__name__,
                     velocity=ctx.velocity, warnings={k: w for k, w in warnings.items() if w},
                     trials=state.trials, search=search,
                     derivatives=None if v is not None else {"method": derivatives,
                                                             "window_s": velocity_window})
