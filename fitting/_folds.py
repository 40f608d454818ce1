"""A large held-out gain seen on too few episodes: confirm it on the other held-out folds.

The diagnosis holds out every third of its time blocks (fold 2 of three,
`fitting._regimes.holdout_mask`). An effect confined to a regime the motion visits rarely
(a drag at the few fast strokes, a warm-up over the first minute) then has its held-out
gain in two or three episodes, however large it is: the batch means of `fitting._evidence`
see a few large gains among many batches where the effect does nothing, and ``t`` stays
low (on the diagnosis bench's two-state truth, a drag after a drift removed 42 % of the
held-out SSE, almost all of it in two batches of 42: ``t = 1.4``).

A statistician would not weaken the test but gather more held-out data: blocked
cross-validation. `on_all_folds` refits the model without and with the effect on the
training blocks of each of the two other folds (fold 0 and fold 1 held out in turn,
each fit starting from the fold-2 fits), so that every sample is held out once, and
applies the same evidence (`fitting._evidence.evidence`: batch means where the effect
acts) to the residuals of all three folds together: three times the episodes. The
decision is the same rule (`fitting._evidence.convincing`) on the share of the SSE of
every sample removed and that ``t``.

It costs four refits, so the diagnosis asks for it only where the single split is
inconclusive but the held-out gain large (at least `fitting._evidence.STRONG_SHARE`).
"""

import dataclasses

import numpy as np

from ._diagnose_context import _Context, _step
from ._evidence import evidence


@dataclasses.dataclass
class FoldEvidence:
    """Held-out evidence over the three folds: `removed` (share of the SSE of all samples,
    each held out once, removed by the effect), `t` and `batches` (`fitting._evidence`)."""

    removed: float
    t: float
    batches: int

    def words(self) -> str:
        return (f"on all three held-out folds (every sample held out once) it removed "
                f"{100 * self.removed:.3g} % of the SSE, consistent over {self.batches} "
                f"batches (t = {self.t:.1f})")


def on_all_folds(ctx: _Context, current, added_before, trial_model, added_after,
                 resid, trial_resid) -> FoldEvidence:
    """The evidence that `trial_model` (with the new effects) improves on `current` when
    each of the three folds is held out in turn. `resid`, `trial_resid`: their residuals
    from fits on the training set of fold 2 (`ctx.train`), as the diagnosis has them."""
    fold = ctx.block % 3
    ref, new = np.array(resid, np.float64), np.array(trial_resid, np.float64)
    for k in (0, 1):
        test = fold == k
        train = ~test
        for model, added, out in ((current, added_before, ref),
                                  (trial_model, added_after, new)):
            _, r = _step(model, added, ctx.t, ctx.x, ctx.v, ctx.F, train, test, ctx.masks,
                         ctx.log, ctx.max_steps, ctx.fixed, restart=True, load=ctx.load,
                         a=ctx.a)
            out[test] = r[test]
    ev = evidence(ref, new, np.ones(ref.shape, bool), ctx.v_arr)
    removed = 1.0 - float(np.sum(new**2)) / max(float(np.sum(ref**2)), 1e-300)
    return FoldEvidence(removed=removed, t=ev.t, batches=ev.batches)
