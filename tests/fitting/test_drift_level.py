"""A drift's starting level per run (`jaxfric.effects.Drift.drift_level`, declared
``per_run="relative"``): the term against NumPy, its recovery from two runs whose levels
differ (run 1 the reference at 0), the plain model of each run and of a run not fitted, a
fit of one run unchanged (the level held at 0), its gradient against finite differences,
and the C export."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fitting
import jaxfric
from fitting._per_run import per_run_values, shifted, with_runs
from jaxfric import effects, examples, paper
from jaxfric._fields import parameter_info


TRUTH = paper.tustin()
RATE = 1e-3  # 1/s: 0.1 % of the base friction per second, shared by the runs
LEVELS = (0.0, 0.04)  # each run's starting level, a fraction of the base friction
NOISE = 0.02  # N


def _runs(levels=LEVELS):
    """Two runs of one machine (other motions, other rates) starting at other levels."""
    runs = []
    for seed, (dt, level) in enumerate(zip((1e-2, 2e-2), levels)):
        t, x = examples.diagnosis_motion(dt=dt, seed=seed)
        F = np.asarray(jaxfric.simulate(
            TRUTH + effects.Drift(drift_rate=RATE, drift_level=level), t, x))
        runs.append(fitting.Dataset(
            t=t, x=x, F=F + NOISE * np.random.default_rng(seed).normal(size=t.size)))
    return runs


def test_drift_term_against_numpy():
    t, x = examples.diagnosis_motion(dt=2e-2, seed=4)
    t = t + 7.0  # the term reads the time since the first sample
    level, rate, decay = 0.03, 2e-3, 0.05
    model = TRUTH + effects.Drift(drift_rate=rate, drift_decay=decay, drift_level=level)
    base = np.asarray(jaxfric.simulate(TRUTH, t, x))
    el = t - t[0]
    want = base * (1.0 + level + rate * -np.expm1(-decay * el) / decay)
    np.testing.assert_allclose(np.asarray(jaxfric.simulate(model, t, x)), want, rtol=1e-12,
                               atol=1e-12)


def test_level_is_declared_relative_per_run():
    infos = {i.name: i.per_run for i in parameter_info(TRUTH + effects.Drift())}
    assert infos["drift_level"] == "relative" and not infos["drift_rate"]


@pytest.fixture(scope="module")
def two_runs():
    runs = _runs()
    return runs, fitting.fit_datasets(TRUTH + effects.Drift(), runs)


def test_two_runs_recover_the_level_difference(two_runs):
    _, res = two_runs
    assert bool(res.converged)
    assert "drift_level_2" in res.params
    assert not {"drift_level", "drift_level_1"} & set(res.params)  # run 1: the reference
    level, err = float(res.params["drift_level_2"]), float(res.stderr["drift_level_2"])
    assert 0 < err < 1e-3
    assert abs(level - (LEVELS[1] - LEVELS[0])) <= 3 * err
    assert abs(float(res.params["drift_rate"]) - RATE) <= 3 * float(res.stderr["drift_rate"])
    for name in ("Fs", "Fc"):  # shared: the truth's, not a blend of the two levels
        np.testing.assert_allclose(float(res.params[name]),
                                   float(fitting.natural_params(TRUTH)[name]), rtol=2e-3)


def test_run_models_and_the_mean_model(two_runs):
    runs, res = two_runs
    level = float(res.params["drift_level_2"])
    for i, d in enumerate(runs):
        model = fitting.run_model(res.fit_model, i)
        assert type(model.effects[0]) is effects.Drift
        assert float(model.effects[0].drift_level) == (0.0, level)[i]
        np.testing.assert_array_equal(np.asarray(jaxfric.simulate(model, d.t, d.x)),
                                      np.asarray(res.prediction[i]))
    assert [v["drift_level"] for v in per_run_values(res.fit_model)] == [0.0, level]
    mean = fitting.run_model(res.fit_model, None)  # a run not fitted
    np.testing.assert_allclose(float(mean.effects[0].drift_level), level / 2, rtol=1e-15)
    assert jaxfric.load_model(jaxfric.model_to_dict(mean)) is not None


def test_one_run_holds_the_level_and_fits_what_it_did_without_it():
    d = _runs()[1]
    start = TRUTH + effects.Drift()
    res = fitting.fit(start, d.t, d.x, d.F)
    assert "drift_level" not in res.free and float(res.params["drift_level"]) == 0.0
    others = [n for n in fitting._params.leaf_names(start) if n != "drift_level"]
    assert set(res.free) == set(others)
    same = fitting.fit(start, d.t, d.x, d.F, free=others)  # every other parameter free
    for name, value in same.params.items():  # equal but for XLA's threads (docs/fitting.md)
        err = float(same.stderr[name])
        tol = 0.05 * err if err > 0 else 1e-12
        assert abs(float(res.params[name]) - float(value)) <= tol, name
    # the level is absorbed by the base friction: run 2's Fc is 4 % above the truth's
    np.testing.assert_allclose(float(res.params["Fc"]), 1.04 * float(TRUTH.stribeck.Fc),
                               rtol=5e-3)


def test_gradient_of_the_per_run_level_against_finite_differences():
    runs = [fitting.Dataset(t=d.t[:800], x=d.x[:800], F=d.F[:800]) for d in _runs()]
    runs = shifted(runs)
    model = with_runs(TRUTH + effects.Drift(drift_rate=RATE, drift_level=0.01), 2)
    model = eqx.tree_at(lambda m: m.effects[0].effect.drift_level, model,
                        jnp.asarray([0.03]))

    def loss(m):
        return sum(jnp.sum((jaxfric.simulate(m, d.t, d.x) - d.F) ** 2) for d in runs)

    def level(m):
        return m.effects[0].effect.drift_level

    grad = jaxfric._compile.jit(jax.grad(loss))(model)
    loss_j = jaxfric._compile.jit(loss)
    h = 1e-6
    fd = (loss_j(eqx.tree_at(level, model, jnp.asarray([0.03 + h])))
          - loss_j(eqx.tree_at(level, model, jnp.asarray([0.03 - h])))) / (2 * h)
    np.testing.assert_allclose(float(level(grad)[0]), float(fd), rtol=1e-6)
    # only run 2 depends on it: its residual against the base force, times 2
    m2 = fitting.run_model(model, 1)
    base = jaxfric.simulate(TRUTH, runs[1].t, runs[1].x)
    want = 2 * jnp.sum((jaxfric.simulate(m2, runs[1].t, runs[1].x) - runs[1].F) * base)
    np.testing.assert_allclose(float(level(grad)[0]), float(want), rtol=1e-9)


def test_export_is_of_one_run_or_the_mean_model(two_runs, tmp_path):
    from jaxfric.export import compile_c, ExportError, find_compiler, to_c

    runs, res = two_runs
    with pytest.raises(ExportError, match=r"one value per run.*run_model\(model, None\)"):
        to_c(res.fit_model, tmp_path / "wrapped")
    mean = fitting.run_model(res.fit_model, None)
    header, source = to_c(mean, tmp_path / "mean")
    assert "JF_DRIFT_LEVEL" in source.read_text() + header.read_text()
    if find_compiler() is None:
        pytest.skip("no C compiler: 'cc' is not on the PATH")
    compiled = compile_c(mean, tmp_path / "built")
    d = runs[1]
    v = np.r_[0.0, np.diff(d.x) / np.diff(d.t)]
    want = np.asarray(jaxfric.simulate(mean, d.t, d.x, v))
    np.testing.assert_allclose(compiled.run(d.t, d.x, v), want, rtol=0,
                               atol=1e-9 * np.max(np.abs(want)))


def _three_runs(seconds=20.0):
    """Three runs of a small Tustin stage with one drift rate and three starting levels."""
    model = jaxfric.Tustin(jaxfric.Stribeck(Fs=2.0, Fc=1.5, Vs=0.05, delta=2.0), sigma2=1.0)
    runs = []
    for i, level in enumerate((0.0, 0.05, -0.03)):
        t = np.arange(0.0, seconds, 1e-2)
        x = (1 + 0.2 * i) * np.sin(2 * np.pi * t / 2.0)
        v = np.gradient(x, t)
        F = np.asarray(jaxfric.simulate(
            model + effects.Drift(drift_rate=2e-3, drift_level=level), t, x, v))
        runs.append(fitting.Dataset(
            t=t, x=x, v=v, F=F + 0.01 * np.random.default_rng(i).normal(size=t.size)))
    return model, runs


def test_diagnosis_fitter_frees_the_levels_of_runs_2_to_d_when_drift_is_on():
    """The diagnosis's fits (`fitting._refits.Fitter`): the drift slot off holds every
    drift parameter; on, it fits the rate and the levels of runs 2 and 3 (counted as two
    free coordinates); the screening start (`start_effect`) leaves the level at 0."""
    from fitting import _refits as R
    from fitting._candidates import start_effect
    from fitting._diagnose import _records

    model, runs = _three_runs(seconds=10.0)
    data, _ = _records(runs, "central", None)
    fitter = R.Fitter(data, max_steps=100)
    start = fitting.to_fit_representation(model + effects.Drift())
    assert fitter.n_free(start, frozenset({0})) - fitter.n_free(start, frozenset()) == 2 + 2
    off, _ = fitter.fit(start, frozenset())
    assert np.all(np.asarray(off.effects[0].effect.drift_level) == 0.0)
    resid = data.F - data.simulate(off)
    e = start_effect("drift", data, off.without_effects(), resid)
    assert float(e.drift_level) == 0.0 and float(e.drift_rate) > 0
    on, pred = fitter.fit(eqx.tree_at(lambda m: m.effects[0], off, e), frozenset({0}))
    np.testing.assert_allclose(np.asarray(on.effects[0].effect.drift_level), [0.05, -0.03],
                               atol=2e-3)
    assert np.sqrt(np.mean((pred - data.F) ** 2)) < 0.012


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "measured: left out one run at a time, the drift removes 21 % of the held-out SSE (the "
    "held-out run's own level is unknown, only the rate predicts it), z = 1.86 with the "
    "standard error by fold sums of 3 runs: under z = 2, nothing is added"))
def test_diagnosis_of_three_runs_adds_a_drift_with_a_level_per_run():
    model, runs = _three_runs()
    d = fitting.diagnose(model, runs, effects=["drift", "offset"], base_models=())
    assert d.folds == "runs" and d.final.added == ["drift"]
    levels = [float(d.final.fit.params[f"drift_level_{i}"]) for i in (2, 3)]
    np.testing.assert_allclose(levels, [0.05, -0.03], atol=2e-3)
    assert [r["params"]["drift_level"] for r in d.runs] == [0.0, *levels]
    assert float(d.model.effects[0].drift_level) == pytest.approx(np.mean([0.0, *levels]))
    for row in d.runs:  # each run's held-out error falls with the drift
        assert row["rmse_holdout"][-1] < row["rmse_holdout"][0]
