"""``jaxfric fit``/``compare`` with several runs, ``--validate`` and ``--known-force``
(issue 38): files that differ in rate, units and columns fit to the parameters of a Python
`fitting.fit_datasets`; the validation errors are those of a separate ``simulate`` of the
saved model; per-run offsets; every input is guarded against being overwritten."""

import json
from pathlib import Path

import numpy as np
import pytest

import fitting
import jaxfric
from fitting.cli.main import main
from jaxfric import effects, examples, paper


DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
TRUTH = paper.tustin()


def _motion(seed: int, dt: float):
    return examples.diagnosis_motion(dt=dt, seed=seed)


def _write(path: Path, header: str, columns) -> Path:
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=header, comments="",
               fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Three runs of one Tustin stage: SI at 10 ms; ms/mm/mN at 20 ms; SI at 15 ms with a
    velocity column and a known pulse (mN) added to the force (the run to validate on)."""
    folder = tmp_path_factory.mktemp("runs")
    out = []
    for seed, dt in ((0, 1e-2), (1, 2e-2), (2, 1.5e-2)):
        t, x = _motion(seed, dt)
        F = np.asarray(jaxfric.simulate(TRUTH, t, x))
        F = F + 0.02 * np.random.default_rng(seed).normal(size=t.size)
        if seed == 0:
            out.append(_write(folder / "a.csv", "t,x,F", [t, x, F]))
        elif seed == 1:
            out.append(_write(folder / "b.csv", "t[ms],x[mm],F[mN]", [1e3 * t, 1e3 * x, 1e3 * F]))
        else:
            v = np.asarray(jaxfric.motion.velocity(t, x))
            pulse = np.where((t > 30) & (t < 33), 2.0, 0.0)  # N, written in mN
            out.append(_write(folder / "c.csv", "t,x,v,F,pulse[mN]",
                              [t, x, v, F + pulse, 1e3 * pulse]))
    return out



@pytest.fixture(scope="module")
def fitted(files, tmp_path_factory):
    out = tmp_path_factory.mktemp("out") / "fit.json"
    a, b, c = files
    assert main([str(s) for s in ("fit", a, b, "--validate", c, "--model", "tustin",
                                  "--known-force", "pulse", "--json", out, "--quiet")]) == 0
    return json.loads(out.read_text()), out


def _python_datasets(files):
    runs = []
    for path in files:
        m = jaxfric.data.load(path)
        v, a = fitting.estimate_derivatives(m.t, m.x)  # what the CLI does by default
        runs.append(fitting.Dataset(t=m.t, x=m.x, F=m.F, v=v, a=a))
    return runs


def test_several_files_fit_as_python_fit_datasets(files, fitted):
    saved, _ = fitted
    runs = _python_datasets(files[:2])
    start = fitting.initial_model("tustin", runs[0].t, runs[0].x, runs[0].F, runs[0].v)
    res = fitting.fit_datasets(start, runs, max_steps=200)
    assert saved["files"] == [str(f) for f in files[:2]]
    assert saved["samples"] == sum(r.t.size for r in runs)
    # The same fit to the solver's stopping rule, not in bits (XLA on several threads,
    # docs/fitting.md): a fit stopped by the statistical rule (fitting._stopping) is within
    # sqrt(2 decrease) standard errors of the optimum in every parameter and within
    # `decrease` noise variances of its cost, so two differ by at most twice that in a
    # parameter and by decrease/N of the RMSE (a run's own RMSE, first order in the
    # parameters, by about sqrt(p) 0.28 s^2: under 2/N_run). A parameter the data do not
    # determine (held at its start, no standard error) is not compared, only found in both.
    for why in (res.stopped, saved["stopped"]):
        assert "nothing the data can tell is left" in why, why
    n = sum(r.t.size for r in runs)
    decrease = fitting.Tolerances().decrease
    bound = 2 * np.sqrt(2 * decrease)
    assert set(saved["undetermined"]) == set(res.undetermined)
    for name, value in res.params.items():
        err = float(res.stderr[name])
        if name in res.undetermined:
            continue
        assert abs(saved["params"][name] - float(value)) <= bound * err, name
    np.testing.assert_allclose(saved["rmse"], float(res.rmse), rtol=decrease / n)
    for row, r in zip(saved["runs"], res.residuals):
        np.testing.assert_allclose(row["rmse"], np.sqrt(np.mean(np.asarray(r) ** 2)),
                                   rtol=2 / r.size)


def test_validation_error_is_a_separate_simulate_of_the_saved_model(files, fitted, run,
                                                                  tmp_path):
    saved, path = fitted
    (val,) = saved["validation"]
    assert val["file"] == str(files[2]) and saved["known_force"]["column"] == "pulse"
    sim = tmp_path / "sim.csv"
    rc, _, err = run("simulate", files[2], "--params", path, "--out", sim, "--quiet")
    assert rc == 0, err
    model = np.loadtxt(sim, delimiter=",", skiprows=1)[:, 3]
    m = jaxfric.data.load(files[2], known="pulse")
    resid = model + m.known - m.F
    np.testing.assert_allclose(val["rmse"], np.sqrt(np.mean(resid**2)), rtol=1e-9)
    masks = fitting.regimes(m.t, m.x, m.v, speed_bands=saved["regime_speed_bands"])
    for name, mask in masks.items():
        if mask.any():
            np.testing.assert_allclose(val["regimes"][name]["rmse"],
                                       np.sqrt(np.mean(resid[mask] ** 2)), rtol=1e-9)
    # the pulse (2 N for 3 s) is subtracted, not counted as an error
    assert np.sqrt(np.mean((model - m.F) ** 2)) > 1.5 * val["rmse"]


def _fit_per_run(files, run, folder, name, seed, effect_of_run):
    """``jaxfric fit`` of runs on the motions of `files`, run ``i`` made by ``TRUTH +
    effect_of_run[i]`` with 0.02 N of noise (velocity column: the one simulated with), from
    ``TRUTH`` plus that effect at its defaults; returns the saved JSON and the printed text."""
    paths = []
    for i, effect in enumerate(effect_of_run):
        m = jaxfric.data.load(files[i])
        F = np.asarray(jaxfric.simulate(TRUTH + effect, m.t, m.x))
        F = F + 0.02 * np.random.default_rng(seed + i).normal(size=F.size)
        v = np.asarray(jaxfric.motion.velocity(m.t, m.x))
        paths.append(_write(folder / f"{name}{i}.csv", "t,x,v,F", [m.t, m.x, v, F]))
    start = folder / "start.json"
    jaxfric.save_model(TRUTH + type(effect_of_run[0])(), start)
    out = folder / "fit.json"
    rc, text, err = run("fit", *paths, "--params", start, "--json", out)
    assert rc == 0, err
    return json.loads(out.read_text()), text


def test_per_run_offsets_through_the_command_line(files, run, tmp_path):
    saved, text = _fit_per_run(files, run, tmp_path, "off", 10,
                               [effects.Offset(offset=off) for off in (0.4, -0.1)])
    got = [r["params"]["offset"] for r in saved["runs"]]
    np.testing.assert_allclose(got, [0.4, -0.1], atol=5e-3)
    assert "offset_1" in saved["params"] and "per-run parameters" in text
    mean = jaxfric.load_model(saved["fitted_model"])  # for a run not fitted: the mean
    np.testing.assert_allclose(float(mean.effects[0].offset), np.mean(got), rtol=1e-12)
    for r in saved["runs"]:
        assert float(jaxfric.load_model(r["fitted_model"]).effects[0].offset) == (
            r["params"]["offset"])


def test_drift_levels_per_run_through_the_command_line(files, run, tmp_path):
    """A drift whose starting level differs between two runs: the JSON names the level of
    run 2 (run 1 is the reference, 0) with its standard error, gives each run's level and
    model, and saves the model for a run not fitted (the mean level), which `export`
    writes as C."""
    saved, text = _fit_per_run(files, run, tmp_path, "drift", 20,
                               [effects.Drift(drift_rate=1e-3, drift_level=level)
                                for level in (0.0, 0.04)])
    level, error = saved["params"]["drift_level_2"], saved["stderr"]["drift_level_2"]
    assert 0 < error < 1e-3 and abs(level - 0.04) <= 3 * error
    assert "drift_level_1" not in saved["params"] and "per-run parameters" in text
    assert [r["params"]["drift_level"] for r in saved["runs"]] == [0.0, level]
    for r in saved["runs"]:
        assert float(jaxfric.load_model(r["fitted_model"]).effects[0].drift_level) == (
            r["params"]["drift_level"])
    mean = jaxfric.load_model(saved["fitted_model"])
    np.testing.assert_allclose(float(mean.effects[0].drift_level), level / 2, rtol=1e-12)
    rc, _, err = run("export", tmp_path / "fit.json", "--c", tmp_path / "c")
    assert rc == 0, err
    assert "JF_DRIFT_LEVEL" in (tmp_path / "c" / "jaxfric_model.c").read_text()


def test_compare_several_runs_with_validation(files, run, tmp_path):
    out = tmp_path / "cmp.json"
    rc, text, err = run("compare", files[0], files[1], "--validate", files[2],
                        "--known-force", "pulse", "--models", "tustin,lugre", "--json", out)
    assert rc == 0, err
    saved = json.loads(out.read_text())
    assert set(saved["models"]) == {"tustin", "lugre"}
    for res in saved["models"].values():
        assert [r["role"] for r in res["runs"] + res["validation"]] == [
            "fitted", "fitted", "validation"]
        assert res["validation"][0]["rmse"] > 0
    assert "validation" in text and "RMSE per run and regime" in text


def test_diagnose_several_files_leaves_one_run_out(files, run, tmp_path, monkeypatch):
    """``jaxfric diagnose a.csv b.csv --validate c.csv``: one diagnosis of both runs with
    the runs as folds, each run's held-out error in the table, the JSON and the report, and
    the validation run predicted by the baseline and the diagnosed model. (The search is
    cut to one candidate and no base-model change, to keep the test short: the plumbing is
    tested here, the decision in tests/diagnosis/test_several_runs.py.)"""
    import functools

    from fitting import _diagnose

    monkeypatch.setattr(_diagnose, "diagnose", functools.partial(
        _diagnose.diagnose, effects=("offset",), base_models=()))
    out, report = tmp_path / "diag.json", tmp_path / "report"
    rc, text, err = run("diagnose", files[0], files[1], "--validate", files[2], "--model",
                        "tustin", "--known-force", "pulse", "--json", out, "--report", report)
    assert rc == 0, err
    saved = json.loads(out.read_text())
    assert saved["folds"] == "runs" and saved["files"] == [str(files[0]), str(files[1])]
    assert [Path(r["run"]).name for r in saved["runs"]] == ["a.csv", "b.csv"]
    # the per-run held-out errors are those of fitting.diagnose on the same two runs
    runs = _python_datasets(files[:2])
    start = fitting.initial_model("tustin", runs[0].t, runs[0].x, runs[0].F, runs[0].v)
    d = fitting.diagnose(start, runs, effects=("offset",), base_models=())
    assert d.folds == "runs" and saved["after"]["added"] == d.final.added
    for r, mine in zip(saved["runs"], d.runs):
        assert len(r["rmse_holdout"]) == 1 + len(saved["after"]["added"])
        np.testing.assert_allclose(r["rmse_holdout"], mine["rmse_holdout"], rtol=1e-6)
        assert len(r["rmse"]) == len(r["rmse_holdout"][:2]) and min(r["rmse"]) > 0
    (v,) = saved["validation"]
    assert Path(v["file"]).name == "c.csv"
    assert 0 < v["diagnosed"]["rmse"] and 0 < v["baseline"]["rmse"]
    assert "held-out RMSE per run" in text and "runs not used" in text
    page = (report / "report.html").read_text()
    assert "Error per run" in page and "Runs not used" in page


@pytest.mark.parametrize("which", [1, 2])
def test_outputs_never_overwrite_a_run_or_a_validation_file(files, run, which):
    before = {p: Path(p).read_bytes() for p in files}
    rc, _, err = run("fit", files[0], files[1], "--validate", files[2], "--json", files[which])
    assert rc == 2 and "would overwrite the input" in err
    rc, _, err = run("compare", files[0], files[1], "--validate", files[2], "--json",
                     files[which])
    assert rc == 2 and "would overwrite the input" in err
    assert all(Path(p).read_bytes() == b for p, b in before.items())


def test_a_missing_known_force_column_everywhere_is_one_line(files, run):
    rc, _, err = run("fit", files[0], "--known-force", "push", "--model", "tustin")
    assert rc == 2 and "no column 'push'" in err and len(err.strip().splitlines()) == 1


@pytest.mark.skipif(not (DATA / "emps_validation.csv").exists(),
                    reason="../shared/data is absent")
def test_emps_validation_error_of_the_diagnosed_model(run, tmp_path):
    diag = Path(__file__).resolve().parents[2] / "docs" / "figures" / "emps_diagnosis.json"
    out = tmp_path / "emps.json"
    rc, _, err = run("fit", DATA / "emps_estimation.csv", "--params", diag, "--validate",
                     DATA / "emps_validation.csv", "--max-steps", "0", "--json", out,
                     "--quiet")
    assert rc == 0, err
    saved = json.loads(out.read_text())
    in_sample = json.loads(diag.read_text())["after"]["rmse"]
    # the model as diagnosed: its in-sample error, and a larger one on the other run
    np.testing.assert_allclose(saved["runs"][0]["rmse"], in_sample, rtol=1e-9)
    assert saved["validation"][0]["rmse"] > 2 * in_sample


def test_one_file_with_a_known_force(files, run, tmp_path):
    with_known, without = tmp_path / "k.json", tmp_path / "n.json"
    for out, extra in ((with_known, ["--known-force", "pulse"]), (without, [])):
        rc, _, err = run("fit", files[2], "--model", "tustin", *extra, "--json", out,
                         "--quiet")
        assert rc == 0, err
    k, n = (json.loads(p.read_text()) for p in (with_known, without))
    assert k["known_force"] == {"column": "pulse", "unit": "N"} and "known_force" not in n
    assert "file" in k and "runs" not in k  # the one-file JSON
    assert k["rmse"] < 0.8 * n["rmse"]


def test_what_several_runs_refuse_is_one_line(files, run, tmp_path):
    joints = _write(tmp_path / "joints.csv", "t,q1,q2,tau1,tau2",
                    [np.arange(50) * 1e-2] + [np.sin(np.arange(50) * 0.1)] * 2
                    + [np.cos(np.arange(50) * 0.1)] * 2)
    for argv, words in ((("fit", files[0], joints), "holds several joints"),
                        (("fit", files[0], files[1], "--plot", tmp_path / "p.png"),
                         "--plot takes one file")):
        rc, _, err = run(*argv)
        assert rc == 2 and words in err and len(err.strip().splitlines()) == 1, err


def test_one_file_with_validation(files, run, tmp_path):
    out = tmp_path / "fit.json"
    rc, text, err = run("fit", files[0], "--validate", files[1], "--model", "tustin",
                        "--json", out)
    assert rc == 0, err
    saved = json.loads(out.read_text())
    assert [r["file"] for r in saved["runs"]] == [str(files[0])]
    assert [r["file"] for r in saved["validation"]] == [str(files[1])]
    assert "b.csv" in text and "validation" in text


def test_the_emps_example_adds_the_effects_in_the_order_the_diagnosis_added_them(
        monkeypatch):
    """`examples/emps_validation.py` refits the diagnosed model with its first k effects in
    the order found; the saved model keeps them in an order of its own."""
    from ..helpers import load_example

    ex = load_example("emps_validation")
    starts = []

    def run(extra, params=None):
        starts.append([e["class"] for e in params["effects"]])
        return {"runs": [{"rmse": 1.0}, {"rmse": 2.0}]}

    monkeypatch.setattr(ex, "run", run)
    effects = [{"class": "FrictionLag"}, {"class": "Inertia"}, {"class": "Asymmetry"}]
    diagnosis = {"fitted_model": {"effects": effects},
                 "after": {"added": ["inertia", "asymmetry", "friction_lag"]}}
    rows = ex.effects_added(diagnosis)
    assert starts == [["Inertia"], ["Inertia", "Asymmetry"],
                      ["FrictionLag", "Inertia", "Asymmetry"]]
    assert [r["added"] for r in rows] == [["inertia"], ["inertia", "asymmetry"],
                                          ["inertia", "asymmetry", "friction_lag"]]
