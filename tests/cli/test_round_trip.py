"""A fitted or diagnosed model, saved in its JSON, is the model that was fitted."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import effects as fx, paper
from jaxfric.examples import hidden_effect_measurement

from ..helpers import strokes_with_loops


def _measurement(tmp_path, model, n=1500, seed=0):
    t, x = strokes_with_loops(n, seed)
    F = np.asarray(jaxfric.simulate(model, t, x))
    F = F + 0.02 * np.random.default_rng(seed + 1).normal(size=n)
    path = tmp_path / "m.csv"
    np.savetxt(path, np.column_stack([t, x, F]), delimiter=",", header="t,x,F", comments="")
    return path, t, x, F


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "fitting.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "JAXFRIC_CACHE_DIR": ""})


@pytest.mark.parametrize("kind", ["two-state", "gms", "lugre", "tustin"])
def test_fit_json_simulates_the_fitted_prediction(tmp_path, kind):
    path, _, _, F = _measurement(tmp_path, paper.two_state())
    fit_json, sim_csv = tmp_path / "fit.json", tmp_path / "sim.csv"
    r = _cli("fit", path, "--model", kind, "--max-steps", "40", "--json", fit_json, "--quiet")
    assert r.returncode == 0, r.stderr
    saved = json.loads(fit_json.read_text(),
                       parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert saved["fitted_model"] is not None
    r = _cli("simulate", path, "--params", fit_json, "--out", sim_csv, "--quiet")
    assert r.returncode == 0, r.stderr
    sim = np.loadtxt(sim_csv, delimiter=",", skiprows=1)
    rmse = float(np.sqrt(np.mean((sim[:, 3] - F) ** 2)))
    # The saved fit's own RMSE, recomputed from the reloaded model's simulation.
    assert rmse == pytest.approx(saved["rmse"], rel=1e-9, abs=1e-12)


def test_fit_result_model_reloads_to_its_prediction():
    t = np.linspace(0.0, 6.0, 1201)
    x = 2e-3 * np.sin(2 * np.pi * t / 3.0) + 40e-6 * np.sin(2 * np.pi * t * 1.7)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    res = fitting.fit(paper.two_state(), t, x, F * 1.02, max_steps=10)
    spec = json.loads(json.dumps(jaxfric.model_to_dict(res.fit_model)))
    back = jaxfric.load_model(spec)
    assert isinstance(back.shape, jaxfric.NormalizedPaperShape)
    np.testing.assert_allclose(jaxfric.simulate(back, t, x), res.prediction, rtol=0,
                               atol=1e-9 * np.max(np.abs(F)))


@pytest.mark.slow
def test_diagnosis_json_holds_the_final_model_with_its_effects():
    t, x, F, _ = hidden_effect_measurement("cogging", seed=0, dt=2e-2)
    d = fitting.diagnose(fitting.initial_model("tustin", t, x, F), t, x, F, max_steps=100,
                          derivatives="backward")
    assert "cogging" in d.final.added
    back = jaxfric.load_model(json.loads(json.dumps(d.to_json())))
    assert isinstance(back, fx.WithEffects)
    assert [e.name for e in back.effects] == [e.name for e in d.model.effects]
    np.testing.assert_allclose(jaxfric.simulate(back, t, x), d.final.fit.prediction, rtol=0,
                               atol=1e-9 * np.max(np.abs(F)))


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("kind", ["two-state", "gms", "lugre", "tustin"])
def test_saved_fit_reproduces_its_prediction_bit_for_bit(kind, seed):
    """Over many fits (every model kind, different motions, noise and velocity estimates),
    the model saved in the JSON (`fitted_model`), read back, simulates exactly the fit's
    prediction: not to a tolerance, bit for bit."""
    rng = np.random.default_rng(100 + seed)
    t, x = strokes_with_loops(700, seed)  # one length and step limit: compiled once per kind
    truth = paper.two_state() if seed != 1 else paper.gms(5)
    F = np.asarray(jaxfric.simulate(truth, t, x)) * rng.uniform(0.8, 1.2)
    F = F + 0.05 * rng.normal(size=t.size)
    v = fitting.estimate_velocity(t, x) if seed != 2 else None
    start = fitting.initial_model(kind, t, x, F, fitting.estimate_velocity(t, x))
    res = fitting.fit(start, t, x, F, v, max_steps=12)
    text = json.dumps(jaxfric.model_to_dict(res.fit_model), allow_nan=False)
    back = jaxfric.load_model(json.loads(text))
    again = np.asarray(jaxfric.simulate(back, t, x, v))
    assert np.array_equal(again, np.asarray(res.prediction))
    assert np.array_equal(np.asarray(res.residuals), again - F)
