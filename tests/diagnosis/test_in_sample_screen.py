"""The in-sample screen before cross-validation (`fitting._select._promising`): an option
is cross-validated only when its fit on every sample passes the rule's block test on the
samples it was fitted on; the statistic is the rule's own (`judge`)."""

import numpy as np

from fitting import _select as S


def _options(n=2000, seed=1):
    rng = np.random.default_rng(seed)
    F = rng.standard_normal(n)
    cur = S.Option(("base",), None, frozenset())
    cur.pred = np.zeros(n)
    better = S.Option(("e",), None, frozenset())
    better.pred = 0.5 * F  # removes 75 % of the SSE in every block
    noise = S.Option(("noise",), None, frozenset())
    noise.pred = 0.05 * rng.standard_normal(n)  # fits nothing
    return F, cur, better, noise


def test_the_screen_is_the_rules_statistic_on_the_fits_on_every_sample():
    F, cur, better, noise = _options()
    folds = S.time_block_folds(np.arange(F.size, dtype=float), 20, 4)
    assert S._promising(better, cur, folds, F, 2.0) and better.train_z > 10
    assert not S._promising(noise, cur, folds, F, 2.0) and noise.train_z < 2.0
    # the same numbers as the held-out statistic when the fold predictions are the fits
    cur.fold_preds = [cur.pred] * 4
    noise.fold_preds = [noise.pred] * 4
    S.judge(noise, cur, folds, F)
    assert noise.z == noise.train_z


def test_a_higher_z_screens_out_a_weaker_option():
    F, cur, better, _ = _options()
    folds = S.time_block_folds(np.arange(F.size, dtype=float), 20, 4)
    S._promising(better, cur, folds, F, 2.0)
    assert not S._promising(better, cur, folds, F, better.train_z + 1.0)
