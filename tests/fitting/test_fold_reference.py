"""The reference run of a ``per_run="relative"`` parameter (a drift's starting level) in a
fit that leaves runs out: the first run fitted is the reference, so the leave-one-run-out
fold holding out run 1 is as well posed as the fit of every run (no shift of the fitted
runs' levels confounded with the base friction's scale); re-referencing a wrapped model
(`fitting._per_run.rereferenced`) keeps every run's model."""

import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fitting
import jaxfric
from fitting import _refits as R, _select as S
from fitting._per_run import per_run_values, rereferenced, run_model, shifted, with_runs
from jaxfric import effects
from jaxfric._compile import jit


BASE = jaxfric.Tustin(jaxfric.Stribeck(Fs=2.0, Fc=1.5, Vs=0.05, delta=2.0), sigma2=1.0)
LEVELS = (0.0, 0.05, -0.03)  # each run's starting level, a fraction of the base friction
RATE = 2e-3  # 1/s, shared


def _three_runs(seconds=10.0):
    """Three runs of one stage (other amplitudes) with one drift rate and three levels."""
    runs = []
    for i, level in enumerate(LEVELS):
        t = np.arange(0.0, seconds, 1e-2)
        x = (1 + 0.2 * i) * np.sin(2 * np.pi * t / 2.0)
        v = np.gradient(x, t)
        F = np.asarray(jaxfric.simulate(
            BASE + effects.Drift(drift_rate=RATE, drift_level=level), t, x, v))
        runs.append(fitting.Dataset(
            t=t, x=x, v=v, F=F + 0.01 * np.random.default_rng(i).normal(size=t.size)))
    return runs


@pytest.fixture(scope="module")
def fold_one_out():
    """The diagnosis's fits of the three runs: every run (drift on, from the truth's rate),
    then the fold holding run 1 out, warm-started from that fit (reference run 1). The
    Stribeck shape (Vs, delta), which these sine motions hardly determine (|corr| near 1
    in every fold, whichever run is out), is held at the truth's."""
    from fitting._diagnose import _records

    data, _ = _records(_three_runs(), "central", None)
    fitter = R.Fitter(data, fixed=("Vs", "delta"), max_steps=100)
    start = fitting.to_fit_representation(BASE + effects.Drift(drift_rate=RATE))
    full, _ = fitter.fit(start, frozenset({0}))
    full_res = fitter.last
    folds = S.run_folds(data.t, data.lengths, 6)
    fold, pred = fitter.fold_fit(full, frozenset({0}), folds[0][0])
    return data, full, full_res, fold, fitter.last, pred


def test_full_fit_keeps_run_1_as_the_reference(fold_one_out):
    _, full, res, _, _, _ = fold_one_out
    assert {"drift_level_2", "drift_level_3"} <= set(res.params)
    assert not {"drift_level", "drift_level_1"} & set(res.params)
    assert per_run_values(full)[0]["drift_level"] == 0.0
    assert res.undetermined == ()


def test_fold_without_run_1_is_referenced_to_run_2_and_well_posed(fold_one_out):
    data, full, _, fold, res, pred = fold_one_out
    assert res.undetermined == ()  # no base parameter held for a confounded level shift
    assert bool(res.converged)
    # run 2 is the reference: held at its value in the warm start; run 1 (not fitted)
    # is stored and named, runs 1 and 3 are the fitted leaves
    assert {"drift_level_1", "drift_level_3"} <= set(res.params)
    assert "drift_level_2" not in res.params
    levels = [v["drift_level"] for v in per_run_values(fold)]
    assert levels[1] == per_run_values(full)[1]["drift_level"]
    # the fitted runs' level difference is recovered, with its standard error
    diff, err = levels[2] - levels[1], float(res.stderr["drift_level_3"])
    assert 0 < err < 2e-3
    assert abs(diff - (LEVELS[2] - LEVELS[1])) <= 3 * err + 1e-3
    # the shared parameters are the truth's (not the scale of a level shift)
    for name in ("Fs", "Fc"):
        np.testing.assert_allclose(float(res.params[name]) * (1 + levels[1]),
                                   float(fitting.natural_params(BASE)[name]) * (1 + LEVELS[1]),
                                   rtol=5e-3)
    # run 1, not fitted, is predicted with the levels' mean over runs 2 and 3
    mean = run_model(fold, None, among=[1, 2])
    assert float(mean.effects[0].drift_level) == pytest.approx(np.mean(levels[1:]))
    r1 = data.runs()[0]
    np.testing.assert_allclose(pred[:r1.t.size], np.asarray(jaxfric.simulate(
        mean, r1.t, r1.x, r1.v, load=r1.load, a=r1.a)), rtol=1e-12, atol=1e-12)


def test_fold_jacobian_has_full_rank_over_the_fitted_levels(fold_one_out):
    """No pair of free coordinates of the fold fit with |corr| > 0.99 (run 1's level, with
    no data, has a zero column and is left out)."""
    _, _, _, _, res, _ = fold_one_out
    free = set(res.free)
    idx = [i for i, n in enumerate(res.fit_names) if n != "drift_level_1"
           and (n in free or re.sub(r"_\d+$", "", n) in free)]
    assert {"drift_level_3", "Fs", "Fc"} <= {res.fit_names[i] for i in idx}
    corr = np.asarray(res.corr_fit)[np.ix_(idx, idx)]
    assert np.all(np.isfinite(corr))
    off = np.abs(corr - np.eye(len(idx)))
    assert off.max() < 0.99, off.max()


def _wrapped():
    model = with_runs(BASE + effects.Offset(offset=0.1) + effects.Drift(drift_rate=RATE), 4)
    model = eqx.tree_at(lambda m: m.effects[1].effect.drift_level, model,
                        jnp.asarray([0.02, -0.01, 0.04]))
    return eqx.tree_at(lambda m: m.effects[0].effect.offset, model,
                       jnp.asarray([0.1, 0.2, 0.3, 0.4]))


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_rereferencing_keeps_every_runs_model(k):
    model = _wrapped()
    moved = rereferenced(model, k)
    drift = moved.effects[1]
    assert drift.reference_run == k and drift.reference == (
        0.0, 0.02, -0.01, 0.04)[k:k + 1]
    assert np.shape(drift.effect.drift_level) == (3,)
    for i in range(-1, 4):  # -1: the mean model
        a = run_model(model, None if i < 0 else i)
        b = run_model(moved, None if i < 0 else i)
        assert bool(eqx.tree_equal(a, b)), i
    back = rereferenced(moved, 0)
    assert bool(eqx.tree_equal(back, model))
    assert per_run_values(moved) == per_run_values(model)


def test_with_runs_reference_and_names():
    model = with_runs(BASE + effects.Drift(drift_level=0.01), 3, reference=1)
    drift = model.effects[0]
    assert drift.reference_run == 1 and drift.reference == (0.01,)
    names = fitting._params.natural_names(model)
    assert [n for n in names if n.startswith("drift_level")] == ["drift_level_1",
                                                                "drift_level_3"]
    assert bool(eqx.tree_equal(with_runs(model, 3, reference=0),
                               with_runs(BASE + effects.Drift(drift_level=0.01), 3)))
    # no reference given: a wrapped effect stays as it is (`fit_datasets` on a fold's runs)
    assert with_runs(model, 2).effects[0] is drift
    with pytest.raises(ValueError, match=r"3 runs.*4"):
        with_runs(model, 4, reference=0)


def test_gradient_with_run_2_the_reference_against_finite_differences():
    """The stored levels of runs 1 and 3 (run 2 the reference) move runs 1 and 3 only."""
    runs = shifted([fitting.Dataset(t=d.t[:300], x=d.x[:300], v=d.v[:300], F=d.F[:300])
                    for d in _three_runs()])
    model = with_runs(BASE + effects.Drift(drift_rate=RATE, drift_level=0.05), 3,
                      reference=1)
    model = eqx.tree_at(lambda m: m.effects[0].effect.drift_level, model,
                        jnp.asarray([0.01, -0.02]))

    def level(m):
        return m.effects[0].effect.drift_level

    def loss(m, only=(0, 1, 2)):
        return sum(jnp.sum((jaxfric.simulate(m, d.t, d.x, d.v) - d.F) ** 2)
                   for i, d in enumerate(runs) if i in only)

    grad = np.asarray(level(jit(jax.grad(loss))(model)))
    loss_j = jit(loss)
    h = 1e-6
    for j in range(2):
        up = eqx.tree_at(level, model, level(model).at[j].add(h))
        down = eqx.tree_at(level, model, level(model).at[j].add(-h))
        fd = (loss_j(up) - loss_j(down)) / (2 * h)
        np.testing.assert_allclose(grad[j], float(fd), rtol=1e-6)
    # entry 0 is run 1's, entry 1 run 3's: each moves its own run's loss only
    def of_run(i):
        return np.asarray(level(jit(jax.grad(lambda m: loss(m, (i,))))(model)))

    np.testing.assert_array_equal(of_run(1), [0.0, 0.0])  # run 2, the reference
    g1, g3 = of_run(0), of_run(2)
    assert g1[1] == 0.0 and g3[0] == 0.0 and g1[0] != 0.0 and g3[1] != 0.0
    np.testing.assert_allclose(grad, g1 + g3, rtol=1e-12)
