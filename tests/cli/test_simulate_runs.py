"""``jaxfric simulate`` with several files and ``--run K`` (issue 38: several runs in every
command): one CSV per file in the ``--out`` folder, each the force of the model a fit to
several runs saved (per-run parameters at their mean, or run K's own with ``--run K``);
names that would collide and outputs over inputs are refused before any work."""

import json

import numpy as np
import pytest

import jaxfric
from jaxfric import effects, examples, paper


TRUTH = paper.tustin()
OFFSETS = (0.4, -0.1)


def _write(path, t, x, v, F):
    np.savetxt(path, np.column_stack([t, x, v, F]), delimiter=",", header="t,x,v,F",
               comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """Two runs of a Tustin stage with a per-run force offset, fitted together."""
    from fitting.cli.main import main

    folder = tmp_path_factory.mktemp("sim_runs")
    paths = []
    for i, off in enumerate(OFFSETS):
        t, x = examples.diagnosis_motion(dt=1e-2, seed=i)
        v = np.asarray(jaxfric.motion.velocity(t, x))
        F = np.asarray(jaxfric.simulate(TRUTH + effects.Offset(offset=off), t, x, v))
        F = F + 0.02 * np.random.default_rng(20 + i).normal(size=F.size)
        paths.append(_write(folder / f"run{i + 1}.csv", t, x, v, F))
    start = folder / "start.json"
    jaxfric.save_model(TRUTH + effects.Offset(), start)
    fit = folder / "fit.json"
    assert main([str(a) for a in ("fit", *paths, "--params", start, "--json", fit,
                                  "--quiet")]) == 0
    return paths, fit, json.loads(fit.read_text())


def _force(path):
    return np.loadtxt(path, delimiter=",", skiprows=1)[:, 3]


def _expected(model, path):
    m = jaxfric.data.load(path)
    return np.asarray(jaxfric.simulate(model, m.t, m.x, m.v))


def test_several_files_one_csv_each_with_the_mean_model(fitted, run, tmp_path):
    paths, fit, saved = fitted
    out = tmp_path / "forces"
    rc, text, err = run("simulate", *paths, "--params", fit, "--out", out)
    assert rc == 0, err
    assert "at their mean" in text
    mean = jaxfric.load_model(saved["fitted_model"])
    assert sorted(p.name for p in out.iterdir()) == ["run1.csv", "run2.csv"]
    for path in paths:
        np.testing.assert_allclose(_force(out / path.name), _expected(mean, path),
                                   rtol=1e-12, atol=1e-12)


def test_run_k_simulates_that_runs_own_model(fitted, run, tmp_path):
    paths, fit, saved = fitted
    errors = {}
    for k in (None, 2):
        out = tmp_path / f"run{k}.csv"
        rc, _, err = run("simulate", paths[1], "--params", fit, "--out", out,
                         *(("--run", k) if k else ()))
        assert rc == 0, err
        errors[k] = np.sqrt(np.mean((_force(out) - jaxfric.data.load(paths[1]).F) ** 2))
    own = jaxfric.load_model(saved["runs"][1]["fitted_model"])
    np.testing.assert_allclose(_force(tmp_path / "run2.csv"), _expected(own, paths[1]),
                               rtol=1e-12, atol=1e-12)
    # run 2's own offset (-0.1 N) fits its data; the mean (0.15 N) is 0.25 N off
    assert errors[2] < 0.03 < 0.2 < errors[None]


@pytest.mark.parametrize("case", ["run out of range", "run without params",
                                  "same names", "out over an input", "a joint file first"])
def test_what_simulate_refuses_is_one_line(fitted, run, tmp_path, case):
    paths, fit, _ = fitted
    other = tmp_path / "elsewhere"
    other.mkdir()
    twin = _write(other / "run1.csv", *np.loadtxt(paths[0], delimiter=",", skiprows=1).T)
    joints = other / "joints.csv"  # the wide layout of several joints
    np.savetxt(joints, np.random.default_rng(0).random((50, 5)), delimiter=",",
               header="t,q1,tau1,q2,tau2", comments="")
    argv, words = {
        "run out of range": ((paths[0], "--params", fit, "--run", 3), "1 to 2"),
        "run without params": ((paths[0], "--run", 1), "give --params"),
        "same names": ((paths[0], twin, "--out", tmp_path / "f"), "run1.csv"),
        "out over an input": ((paths[0], paths[1], "--out", paths[0].parent),
                              "would overwrite the input"),
        "a joint file first": ((joints, paths[0], "--out", tmp_path / "f"),
                               "simulate a joint file alone"),
    }[case]
    rc, _, err = run("simulate", *argv)
    assert rc == 2 and len(err.strip().splitlines()) == 1 and words in err, err
    assert not (tmp_path / "f").exists()
