"""The three-fold confirmation of a diagnosis refit (`fitting._folds`): every sample held
out once, a real effect confirmed with three times the batches, a refit that adds nothing
credited with nothing."""

import functools

import fitting
from fitting._diagnose_context import _context
from fitting._folds import on_all_folds
from jaxfric import effects as fx
from jaxfric.examples import hidden_effect_measurement


@functools.cache
def _setup(effect):
    t, x, F, _ = hidden_effect_measurement(effect, dt=0.04, seed=3)
    model = fitting.initial_model("two-state", t, x, F)
    ctx = _context(model, t, x, F, None, blocks=24, max_steps=200, fixed=(), min_score=0.05,
                   min_t=3.0, log=None, derivatives="backward", velocity_window=None)
    base, resid = ctx.step(ctx.model, [])
    trial, trial_resid = ctx.step(base.fit.model + fx.Offset(offset=0.0), ["offset"])
    return ctx, base, resid, trial, trial_resid


def test_a_real_offset_is_confirmed_on_all_folds_with_more_batches():
    ctx, base, resid, trial, trial_resid = _setup("offset")
    one = fitting._evidence.evidence(resid, trial_resid, ctx.test, ctx.v_arr)
    folds = on_all_folds(ctx, base.fit.model, [], trial.fit.model, ["offset"], resid,
                         trial_resid)
    assert folds.removed > 0.5, folds
    assert folds.t >= 3.0, folds
    # Every sample is held out once: about three times the single split's batches.
    assert folds.batches >= 2 * one.batches, (folds, one)
    assert "all three held-out folds" in folds.words()
    # An offset acts everywhere: it removes most of the error in each fold.
    assert len(folds.shares) == 3 and folds.replicated(), folds
    assert folds.holds(ctx.min_t, ctx.min_score)


def test_a_refit_that_adds_nothing_gains_nothing():
    ctx, base, resid, *_ = _setup(None)
    folds = on_all_folds(ctx, base.fit.model, [], base.fit.model, [], resid, resid)
    # The same model refitted from the same start on the same folds.
    assert abs(folds.removed) < 1e-9, folds
    assert not folds.holds(ctx.min_t, ctx.min_score), folds
    assert not folds.replicated() and not folds.holds(ctx.min_t, ctx.min_score), folds


def test_an_offset_on_clean_data_is_not_convincing():
    ctx, base, resid, trial, trial_resid = _setup(None)
    folds = on_all_folds(ctx, base.fit.model, [], trial.fit.model, ["offset"], resid,
                         trial_resid)
    assert not fitting._evidence.convincing(folds.removed, folds.t, ctx.min_t), folds
    assert not folds.replicated() and not folds.holds(ctx.min_t, ctx.min_score), folds


def test_replication_rule():
    """`FoldEvidence.holds`: the all-fold rule, or a third of the SSE removed where the effect
    acts in each of the three folds with at least `min_score` of all of it (the two-state
    drag after a drift: 31 %, t 1.8; 84.5, 51.5 and 62 % where it acts)."""
    from fitting._folds import FoldEvidence

    drag = FoldEvidence(removed=0.313, t=1.8, batches=54, shares=(0.845, 0.515, 0.62))
    assert drag.replicated() and drag.holds(3.0, 0.05)
    one_fold_short = FoldEvidence(removed=0.313, t=1.8, batches=54, shares=(0.845, 0.2, 0.62))
    assert not one_fold_short.holds(3.0, 0.05)
    loses_elsewhere = FoldEvidence(removed=0.01, t=0.3, batches=54, shares=(0.8, 0.7, 0.6))
    assert loses_elsewhere.replicated() and not loses_elsewhere.holds(3.0, 0.05)
    consistent = FoldEvidence(removed=0.2, t=3.5, batches=60)
    assert consistent.holds(3.0, 0.05) and not consistent.replicated()
    # Asked for from a held-out gain of 2 * min_score on the one split (a cogging on the GMS
    # truth's clean file, 24.5 %: asked, and it did not replicate: 8.3, -1.6, 33 %; the
    # LuGre truth's friction lag at 10 ms, 18.9 %: asked, and confirmed).
    from fitting._folds import needs_folds

    assert needs_folds(0.245, 0.05) and needs_folds(0.189, 0.05) and needs_folds(0.1, 0.05)
    assert not needs_folds(0.099, 0.05) and not needs_folds(0.19, 0.1)
    # On all folds it must remove at least min_score of the SSE, however consistent: the
    # friction lag above (6.4 %, t 4.4 over 222 batches) holds; a term that removes 2 % of
    # it with the same t does not.
    lag = FoldEvidence(removed=0.064, t=4.4, batches=222, shares=(0.04, 0.28, 0.15))
    assert lag.holds(3.0, 0.05)
    small = FoldEvidence(removed=0.02, t=4.4, batches=222, shares=(0.04, 0.28, 0.15))
    assert not small.holds(3.0, 0.05)
    assert not FoldEvidence(removed=0.04, t=1.0, batches=54, shares=(0.8, 0.7, 0.6)).holds(
        3.0, 0.05)  # replicated, but too small overall
    mismatch = FoldEvidence(removed=0.099, t=1.3, batches=11, shares=(0.083, -0.016, 0.33))
    assert not mismatch.holds(3.0, 0.05)
