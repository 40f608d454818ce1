"""The folds of the diagnosis's cross-validation (`fitting._select`): contiguous time
blocks dealt to folds in turn (`time_block_folds`), or one run held out per fold with its
time blocks (`run_folds`), and the blocks of the rule (`_blocks`)."""

import numpy as np


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
