"""The search copy of a long record (`fitting._search_copy`): the diagnosis ranks and tries
effects on one sample in k, with the force averaged over each window, and refits on all."""

import json

import numpy as np
import pytest

import fitting
import jaxfric
from fitting._diagnose_context import _Context
from fitting._regimes import holdout_mask
from fitting._search_copy import factor, search_context
from jaxfric.examples import hidden_effect_measurement


def test_factor_only_for_long_records():
    assert factor(19_999, 10_000) == 1  # under twice: every sample
    assert factor(20_000, 10_000) == 2
    assert factor(100_038, 10_000) == 10
    assert factor(10**6, None) == factor(10**6, 0) == 1


@pytest.mark.parametrize("k", [5, 4])
def test_copy_is_the_middle_samples_and_the_window_means(k):
    n = 1001
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 10.0, n)
    x, v, F, load = (rng.normal(size=n) for _ in range(4))
    test, block = holdout_mask(t, 24)
    ctx = _Context(model=None, t=t, x=x, v=v, v_arr=v, F=F, train=~test, test=test,
                   block=block, masks={}, log=print, max_steps=1, fixed=(), min_score=0.05,
                   min_t=3.0, velocity="", load=load, blocks=24)
    copy = search_context(ctx, n // k)
    w = k if k % 2 else k + 1  # an even k averages k + 1 samples, centred
    middle = np.arange(w // 2, n - w // 2, k)
    assert np.all(np.diff(middle) == k) and middle.size >= n // k - 1
    np.testing.assert_array_equal(copy.t, t[middle])
    np.testing.assert_array_equal(copy.x, x[middle])
    np.testing.assert_array_equal(copy.v, v[middle])
    # The force and load: the mean over the w samples centred on each kept one.
    for got, full in ((copy.F, F), (copy.load, load)):
        naive = np.array([full[i - w // 2:i + w // 2 + 1].mean() for i in middle])
        np.testing.assert_allclose(got, naive, rtol=1e-12, atol=1e-12)
    # The same time blocks are held out.
    np.testing.assert_array_equal(copy.test, holdout_mask(t[middle], 24)[0])
    assert not copy.train[copy.test].any()
    assert search_context(ctx, n) is ctx  # short enough: no copy


@pytest.fixture(scope="module")
def long_record():
    t, x, F, _ = hidden_effect_measurement(("position_dependence",), seed=0, dt=0.01)
    model = fitting.initial_model("two-state", t, x, F)
    d = fitting.diagnose(model, t, x, F, derivatives="backward", search_samples=3000)
    return t, x, F, d


def test_diagnosis_searches_the_copy_and_reports_on_every_sample(long_record):
    t, _, F, d = long_record
    assert "one sample in 3" in d.search and f"all {t.size} samples" in d.search
    assert "search:" in d.summary() and d.to_json()["search"] == d.search
    assert d.final.added == ["position_dependence"], d.summary()
    assert d.holdout.size == t.size
    for step in (d.baseline, *d.steps):
        # Every number is of the whole record: the prediction has every sample, and the
        # RMSEs are its errors there.
        resid = np.asarray(step.fit.prediction) - F
        assert resid.size == t.size
        assert step.rmse == pytest.approx(np.sqrt(np.mean(resid**2)), rel=1e-9)
        assert step.rmse_holdout == pytest.approx(
            np.sqrt(np.mean(resid[d.holdout] ** 2)), rel=1e-9)
    assert d.final.rmse <= 0.6 * d.baseline.rmse, d.summary()
    # The searched rankings are of the copy (a third of the samples), the trials too.
    assert d.trials and all(trial["effects"] for trial in d.trials)
    # Each says why it was tried and which of its two refits was kept.
    assert all(trial["tried_as"] in fitting._diagnose.TRIED_AS
               and trial["start"] in ("fitted model", "starting model") for trial in d.trials)
    assert [trial["tried_as"] for trial in d.trials if trial["added"]] == ["significant"]


def test_searched_diagnosis_saves_the_model_of_its_full_rate_refit(long_record):
    """The JSON's model, read back and simulated on every sample with the diagnosis's
    velocity, is the final step's prediction (the full-rate refit, not the search's)."""
    t, x, F, d = long_record
    back = jaxfric.load_model(json.loads(json.dumps(d.to_json())))
    v = fitting.estimate_velocity(t, x, "backward")  # the diagnosis's derivatives
    np.testing.assert_allclose(jaxfric.simulate(back, t, x, v), d.final.fit.prediction,
                               rtol=0, atol=1e-9 * np.max(np.abs(F)))
