"""The rule for nearly equal candidates (`fitting._diagnose._closest_call`): a held-out
error that is significantly lower decides, otherwise the higher screen score."""

from types import SimpleNamespace as NS

import numpy as np

from fitting._diagnose import _closest_call


def _ctx(n):
    test = np.zeros(n, bool)
    test[::3] = True
    return NS(test=test, v_arr=np.ones(n), min_t=3.0)


def _held(name, score, resid, test):
    step = NS(rmse_holdout=float(np.sqrt(np.mean(resid[test] ** 2))))
    return NS(name=name, score=score), (step, resid)


def test_single_survivor_is_chosen():
    ctx = _ctx(30)
    only = _held("offset", 0.4, np.ones(30), ctx.test)
    assert _closest_call(ctx, [only])[0].name == "offset"


def test_significantly_lower_holdout_error_decides():
    n = 3000
    ctx, rng = _ctx(n), np.random.default_rng(0)
    noise = 0.1 * rng.normal(size=n)
    good = _held("offset", 0.7, noise, ctx.test)
    bad = _held("asymmetry", 0.8, noise + 0.5, ctx.test)  # worse everywhere, higher score
    chosen, why = _closest_call(ctx, [bad, good])
    assert chosen.name == "offset" and "better" in why


def test_indistinguishable_refits_go_to_the_higher_score():
    n = 3000
    ctx, rng = _ctx(n), np.random.default_rng(1)
    a = 0.1 * rng.normal(size=n)
    b = 0.1 * rng.normal(size=n)  # the same error, other noise: no significant difference
    for scores, name in (((0.7, 0.8), "asymmetry"), ((0.8, 0.7), "offset")):
        first = _held("offset", scores[0], a, ctx.test)
        second = _held("asymmetry", scores[1], b, ctx.test)
        chosen, why = _closest_call(ctx, [first, second])
        assert chosen.name == name and "not significant" in why
