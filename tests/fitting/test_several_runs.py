"""Several runs in one fit: per-run nuisance parameters (`param(..., per_run=True)`) and
known force components (`Dataset(known=...)`, `jaxfric.data.load(..., known=...)`)."""

import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import effects, examples, paper
from jaxfric._fields import parameter_info


OFFSETS = (0.3, -0.2, 0.1)  # N, one per run


def _runs(model, offsets=OFFSETS, noise=0.02):
    """Three runs of `model` plus a run-specific offset: other motions, other rates."""
    runs = []
    for seed, (dt, off) in enumerate(zip((1e-2, 2e-2, 1.5e-2), offsets)):
        t, x = examples.diagnosis_motion(dt=dt, seed=seed)
        F = jaxfric.simulate(model + effects.Offset(offset=off), t, x)
        F = np.asarray(F) + noise * np.random.default_rng(seed).normal(size=t.size)
        runs.append(fitting.Dataset(t=t, x=x, F=F))
    return runs


def test_offset_is_declared_per_run_and_others_are_not():
    infos = {i.name: i.per_run for i in parameter_info(paper.two_state() + effects.Offset()
                                                       + effects.Viscous())}
    assert infos["offset"] and not infos["c_visc"] and not infos["Fs"]


@pytest.fixture(scope="module")
def per_run_fit():
    truth = paper.tustin()
    runs = _runs(truth)
    return truth, runs, fitting.fit_datasets(truth + effects.Offset(), runs)


def test_per_run_offsets_are_fitted_per_run_and_the_rest_shared(per_run_fit):
    truth, _, res = per_run_fit
    assert bool(res.converged)
    got = [float(res.params[f"offset_{i + 1}"]) for i in range(3)]
    np.testing.assert_allclose(got, OFFSETS, atol=5e-3)
    for i in range(3):  # each value is determined by its own run
        assert 0 < float(res.stderr[f"offset_{i + 1}"]) < 2e-3
    for name in ("Fs", "Fc", "sigma2"):  # shared: one value, the truth's
        np.testing.assert_allclose(float(res.params[name]), float(
            fitting.natural_params(truth)[name]), rtol=2e-2)
    assert "offset" not in res.params


def test_run_models_reproduce_the_prediction_of_each_run(per_run_fit):
    _, runs, res = per_run_fit
    for i, d in enumerate(runs):
        model = fitting.run_model(res.fit_model, i)
        assert type(model.effects[0]) is effects.Offset
        np.testing.assert_allclose(float(model.effects[0].offset),
                                   float(res.params[f"offset_{i + 1}"]), rtol=0, atol=0)
        np.testing.assert_array_equal(np.asarray(jaxfric.simulate(model, d.t, d.x)),
                                      np.asarray(res.prediction[i]))
    mean = fitting.run_model(res.fit_model, None)
    np.testing.assert_allclose(float(mean.effects[0].offset),
                               np.mean([float(res.params[f"offset_{i + 1}"]) for i in range(3)]))
    # saved and loaded as an ordinary model
    assert jaxfric.load_model(jaxfric.model_to_dict(mean)) is not None


def test_one_dataset_keeps_one_offset():
    truth = paper.tustin()
    d = _runs(truth)[0]
    res = fitting.fit(truth + effects.Offset(), d.t, d.x, d.F)
    assert "offset" in res.params and "offset_1" not in res.params
    np.testing.assert_allclose(float(res.params["offset"]), OFFSETS[0], atol=5e-3)


def test_known_force_is_subtracted_not_fitted():
    truth = paper.tustin()
    t, x = examples.diagnosis_motion(dt=1e-2, seed=3)
    pulse = np.where((t > 20) & (t < 22), 5.0, 0.0)  # a known external force, N
    F = np.asarray(jaxfric.simulate(truth, t, x)) + pulse
    F = F + 0.02 * np.random.default_rng(3).normal(size=t.size)
    with_known = fitting.fit(truth, t, x, F, known=pulse)
    subtracted = fitting.fit(truth, t, x, F - pulse)
    # The same fit: equal to a small fraction of each standard error (not bit for bit: XLA's
    # CPU runtime is not bit-reproducible on more than one thread, docs/fitting.md).
    for name, value in with_known.params.items():
        err = float(with_known.stderr[name])
        tol = 0.05 * err if np.isfinite(err) and err > 0 else 1e-6 * abs(float(value))
        assert abs(float(value) - float(subtracted.params[name])) <= tol, name
    np.testing.assert_allclose(np.asarray(with_known.prediction),
                               np.asarray(jaxfric.simulate(with_known.fit_model, t, x)))
    np.testing.assert_allclose(np.asarray(with_known.residuals),
                               np.asarray(with_known.prediction) + pulse - F, atol=1e-12)
    assert float(with_known.rmse) < 0.03
    ignored = fitting.fit(truth, t, x, F)  # the pulse fitted as friction: much worse
    assert float(ignored.rmse) > 10 * float(with_known.rmse)


def test_load_reads_a_known_force_column_in_its_unit(tmp_path):
    t = np.arange(200) * 1e-2
    x = 1e-3 * np.sin(t)
    F = 2.0 * np.tanh(1e3 * np.cos(t))
    pulse_mN = np.where(t > 1, 500.0, 0.0)
    path = tmp_path / "run.csv"
    np.savetxt(path, np.column_stack([t, x, F + 1e-3 * pulse_mN, pulse_mN]), delimiter=",",
               header="t,x,F,pulse[mN]", comments="")
    m = jaxfric.data.load(path, known="pulse")
    np.testing.assert_allclose(m.known, 1e-3 * pulse_mN)
    assert "pulse" not in m.extra and any("known force" in n for n in m.notes)
    flipped = jaxfric.data.load(path, known="pulse", flip_force=True)
    np.testing.assert_allclose(flipped.known, -1e-3 * pulse_mN)
    with pytest.raises(jaxfric.data.DataError, match="no column 'push'"):
        jaxfric.data.load(path, known="push")
