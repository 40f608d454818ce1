"""The diagnosis's base fit races the given start and a fast-lag start
(`fitting._start.lag_starts`, `fitting._refits.Fitter.race`): from a slow friction lag
(seconds) a two-state fit can settle where the lag acts as a memory of the motion, far
off the fit from a fast lag. The record: the stiction truth with hidden inertia and
cogging on a jerk-limited motion (`jaxfric.synthetic.measurement`, as the diagnosis
bench makes its files), 10 s at 10 ms; `initial_model` starts it at the 2.4 s lag."""

import equinox as eqx
import numpy as np
import pytest

import fitting
import jaxfric
from fitting._diagnose import _inputs
from fitting._params import to_fit_representation
from fitting._refits import Fitter
from fitting._start import lag_starts, LAG_TIMES
from jaxfric import effects as fx, paper
from jaxfric.synthetic import measurement


def _two_state(C):
    stribeck = jaxfric.Stribeck(Fs=26.0, Fc=20.0, Vs=1e-3, delta=1.0)
    return jaxfric.TwoState(stribeck=stribeck, shape=paper.shape(), sigma2=50.0, C=C)


def test_lag_starts_add_the_fastest_lag_only_to_a_model_with_a_slower_lag():
    slow = _two_state(9.0)  # Fs/C = 2.9 s
    (given, m0), (fast, m1) = lag_starts(slow)
    assert (given, fast) == ("given start", "fast-lag start") and m0 is slow
    assert float(m1.stribeck.Fs) / float(m1.C) == pytest.approx(min(LAG_TIMES), rel=1e-12)
    assert float(m1.sigma2) == float(slow.sigma2)
    # with effects: the base model's lag, the effects as they were
    (_, w0), (_, w1) = lag_starts(slow + fx.Offset(offset=1.5))
    assert float(w1.without_effects().C) == pytest.approx(26.0 / min(LAG_TIMES), rel=1e-12)
    assert float(w1.effects[0].offset) == 1.5 and float(w0.without_effects().C) == 9.0
    gms = jaxfric.GMS.from_shape(slow.shape, slow.stribeck, 50.0, 9.0, 5)
    assert float(lag_starts(gms)[1][1].C) == pytest.approx(26.0 / min(LAG_TIMES), rel=1e-12)
    # a lag held at its value (`fixed`), a lag as fast already, and models without a
    # friction lag: the given start alone
    assert lag_starts(slow, ("C",)) == [("given start", slow)]
    assert len(lag_starts(_two_state(26.0 / min(LAG_TIMES)))) == 1
    stribeck = slow.stribeck
    assert len(lag_starts(jaxfric.Tustin(stribeck=stribeck, sigma2=50.0))) == 1
    assert len(lag_starts(jaxfric.LuGre(stribeck=stribeck, sigma0=1e5, sigma1=300.0,
                                        sigma2=50.0))) == 1


@pytest.fixture(scope="module")
def record():
    t, x, F = measurement("stiction", ("inertia", "cogging"), 0.03, 0.01, 12,
                          motion="jerk_limited", duration=10.0, jitter=0.1)
    start = fitting.initial_model("two-state", t, x, F, fitting.estimate_velocity(t, x))
    return t, x, F, to_fit_representation(start)


def _lag(m) -> float:
    return float(m.stribeck.Fs) / float(m.C)


def test_the_race_keeps_the_fast_lag_fit_where_the_slow_lag_start_settles_in_a_memory(record):
    t, x, F, start = record
    assert _lag(start) == pytest.approx(max(LAG_TIMES))  # the premise: a slow-lag start
    full = _inputs(t, x, F, None, None, None, "central", None)[0]
    f = Fitter(full, (), 150)
    poor, pred = f.fit(start, frozenset())
    poor_rmse = float(np.sqrt(np.mean((pred - F) ** 2)))
    assert poor_rmse > 1.2 and _lag(poor) > 1.0  # the lag became a memory of the motion
    fitted, pred, won = f.race(lag_starts(start), frozenset())
    rmse = float(np.sqrt(np.mean((pred - F) ** 2)))
    assert won == "fast-lag start"
    assert rmse < 0.5 * poor_rmse and _lag(fitted) < min(LAG_TIMES)
    assert bool(eqx.tree_equal(fitted, f.last.fit_model))  # `last` is the kept fit


def test_the_diagnosis_baseline_is_the_fast_lag_fit_and_says_so(record):
    # search_samples 400: the baseline on every sample races (`diagnose`'s race), and the
    # search starts from the start it kept; the record's reversals keep every sample
    t, x, F, start = record
    lines = []
    d = fitting.diagnose(start, t, x, F, effects=["offset"], base_models=(),
                         search_samples=400, log=lines.append)
    assert d.baseline.start == "fast-lag start"
    assert sum("kept the fit from the" in line for line in lines) == 1  # raced once
    assert d.baseline.rmse < 0.7
    # the folds' fits start where the kept fit did: not from the slow lag (1.86 N)
    assert d.baseline.rmse_holdout < 0.7
    assert "(from the fast-lag start)" in d.summary().splitlines()[0]
    assert d.to_json()["baseline"]["start"] == "fast-lag start"
