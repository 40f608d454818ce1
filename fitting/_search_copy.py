"""The search copy of a long record: a diagnosis ranks and tries its effects on fewer
samples, then refits what it found on all of them.

A diagnosis fits its model many times (the baseline, and two refits with up to five
restarts for every candidate it tries), and a fit's cost grows with the record's length:
each Levenberg-Marquardt step runs the model over every sample. The decisions do not need
every sample: the diagnosis's evidence is counted in batches longer than the residual's
correlation, and its bench (`benchmarks/diagnosis_bench.py`) shows it works at 1e4-2e4
samples over a record. So when a record has at least twice
`SEARCH_SAMPLES` samples, the search runs on one sample in k (``k = n // SEARCH_SAMPLES``):

- time, position, velocity and acceleration are those of the kept samples (the full-rate
  estimates there, as good as they get);
- the force (and a load) is the mean over the window of k samples centred on each kept
  one (k + 1 when k is even, so that it has a middle): a zero-phase boxcar that keeps the
  record's information about anything slower than the window (its noise falls by
  ``sqrt(k)``) and damps faster vibration before it aliases. The copy must still resolve
  the effects, as any record must: a window of a tenth of the fastest effect's period (a
  cogging pitch passed at top speed) attenuates it by 1.6 %, of a fifth by 6.5 %; past
  that, `search_samples` should be raised (or 0: every sample);
- the held-out split is the same time blocks (`fitting._regimes.holdout_mask`).

Then the baseline and each step's model are refitted on all samples, from where the search
left them (`at_full_rate`): every number a user reads (RMSEs, regimes, parameters, the
final model) is of the whole record; the rankings and the trials' errors are of the copy.
"""

import dataclasses

import numpy as np

from ._regimes import holdout_mask, regimes


#: A diagnosis searches on about this many samples when the record has twice as many.
SEARCH_SAMPLES = 10_000


def factor(n: int, samples: int | None) -> int:
    """The search copy keeps one sample in this many (1: no copy)."""
    if not samples or n < 2 * samples:
        return 1
    return n // samples


def _window_mean(y: np.ndarray, w: int, middle: np.ndarray) -> np.ndarray:
    """The mean of `y` over the `w` samples (odd) centred on each of `middle`."""
    c = np.r_[0.0, np.cumsum(y)]
    start = middle - w // 2
    return (c[start + w] - c[start]) / w


def search_context(ctx, samples: int | None):
    """The `fitting._diagnose_context._Context` `ctx` on its search copy (see the module
    docstring), or `ctx` itself when the record is short enough."""
    k = factor(ctx.t.size, samples)
    if k == 1:
        return ctx
    w = k | 1  # the window: k, or k + 1 when k is even
    middle = np.arange(w // 2, ctx.t.size - w // 2, k)
    t, x, v = ctx.t[middle], ctx.x[middle], ctx.v[middle]
    test, block = holdout_mask(t, ctx.blocks)
    return dataclasses.replace(
        ctx, t=t, x=x, v=v, v_arr=v, a=None if ctx.a is None else ctx.a[middle],
        F=_window_mean(ctx.F, w, middle),
        load=None if ctx.load is None else _window_mean(ctx.load, w, middle),
        train=~test, test=test, block=block, masks=regimes(t, x, v))


def describe(ctx, search) -> str:
    """The search copy in words (empty when there is none)."""
    if search is ctx:
        return ""
    k = round(ctx.t.size / search.t.size)
    return (f"effects ranked and tried on one sample in {k} ({search.t.size} samples, the "
            f"force averaged over {k | 1} around each); the baseline and every step "
            f"refitted on all {ctx.t.size} samples")


def at_full_rate(ctx, search, baseline, steps):
    """``(baseline, steps)`` refitted on all samples of `ctx` from the search's models
    (the same `baseline`, `steps` when there was no copy)."""
    if search is ctx:
        return baseline, steps
    out = []
    for i, s in enumerate([baseline, *steps]):
        what = "the baseline" if i == 0 else " + ".join(s.added)
        ctx.log(f"refitting {what} on all {ctx.t.size} samples ...")
        out.append(ctx.step(s.fit.model, s.added, restart=True)[0])
    return out[0], out[1:]
