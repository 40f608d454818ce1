"""When the screen finds nothing that holds up, the leading candidates are refitted
(`fitting._diagnose._try_leaders`): which ones."""

import types

import numpy as np

from fitting._candidates import Candidate
from fitting._diagnose import _leaders, _State
from jaxfric import effects as fx


def test_leaders_are_the_best_scores_not_yet_refitted():
    """`fitting._diagnose._leaders`: when nothing held up, the three best scores of at least
    2 * min_score are refitted, except those already refitted alone this round."""
    def cand(name, score):
        return Candidate(name, fx.Offset(), score, 1.0, False, "", "")

    ranking = [cand("stribeck", 0.177), cand("inertia", 0.154), cand("drift", 0.076),
               cand("cogging", 0.12)]
    ctx = types.SimpleNamespace(min_score=0.05)
    state = _State(current=None, resid=np.zeros(3), best_holdout=1.0, added=[])
    assert [c.name for c in _leaders(ctx, state, ranking)] == ["stribeck", "inertia"]
    state.trials.append({"round": 0, "effects": ["stribeck"]})
    assert [c.name for c in _leaders(ctx, state, ranking)] == ["inertia"]
    state.added.append("offset")  # a new round: tried again
    assert [c.name for c in _leaders(ctx, state, ranking)] == ["stribeck", "inertia"]
    assert _leaders(types.SimpleNamespace(min_score=0.1), state, ranking) == []


def test_each_refit_says_why_it_was_tried(monkeypatch):
    """The trial records say why a refit was tried (`fitting._diagnose.TRIED_AS`): the
    leading candidates as such, the largest but inconsistent score as such, the
    significant ones as significant."""
    import fitting._diagnose as D

    seen = []

    def refit(ctx, state, effects, names, why):  # nothing holds up
        seen.append((tuple(names), why))
        return None, None, False, 0.0, 0, 0.0

    monkeypatch.setattr(D, "_refit", refit)

    def cand(name, score, significant=False):
        return Candidate(name, fx.Offset(), score, 1.0, significant, "", "")

    ctx = types.SimpleNamespace(min_score=0.05, min_t=3.0, log=lambda *a: None)
    state = _State(current=None, resid=np.zeros(3), best_holdout=1.0, added=[])
    ranking = [cand("stribeck", 0.25), cand("inertia", 0.154, significant=True),
               cand("drift", 0.03)]
    assert D._try_singles(ctx, state, ranking) == (None, None, None)
    assert D._try_leaders(ctx, state, ranking) == (None, None, None)
    assert seen == [(("stribeck",), "largest score"), (("inertia",), "significant"),
                    (("stribeck",), "leading"), (("inertia",), "leading")]
    assert {why for _, why in seen} <= set(D.TRIED_AS)
