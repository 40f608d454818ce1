"""`jaxfric simulate --stack-size/--deadband`: memory overflow on noisy standstill is
reported with what to do, and the deadband ('auto': estimated from the positions) removes
it."""

import json

import numpy as np

import jaxfric
from jaxfric import paper

from .test_cli import run
from .test_direction import standstill_motion


def test_simulate_reports_overflow_and_deadband_removes_it(tmp_path):
    t, x, _ = standstill_motion(11)
    t, x = t[:4000], x[:4000]
    data = tmp_path / "joint.csv"
    np.savetxt(data, np.column_stack([t, x]), delimiter=",", header="t[s],x[m]",
               comments="", fmt="%.17g")
    out = tmp_path / "sim.csv"
    raw = run("simulate", data, "--stack-size", 4, "--out", out)
    assert raw.returncode == 0, raw.stderr
    assert "overflowed" in raw.stderr and "--stack-size" in raw.stderr
    played = run("simulate", data, "--stack-size", 4, "--deadband", "auto", "--out", out)
    assert played.returncode == 0, played.stderr
    assert "overflowed" not in played.stderr
    assert "deadband: " in played.stdout
    bad = run("simulate", data, "--deadband", "wide", "--out", out)
    assert bad.returncode != 0 and "--deadband" in bad.stderr
    small = run("simulate", data, "--stack-size", 0, "--out", out)
    assert small.returncode != 0 and "--stack-size" in small.stderr


def test_fit_records_the_deadband_and_simulate_params_reuses_it(tmp_path):
    t, x, x_true = standstill_motion(12)
    t, x, x_true = t[:3000:2], x[:3000:2], x_true[:3000:2]
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x_true))
    data = tmp_path / "run.csv"
    np.savetxt(data, np.column_stack([t, x, F]), delimiter=",", header="t[s],x[m],F[N]",
               comments="", fmt="%.17g")
    r = run("fit", data, "--model", "tustin", "--deadband", "auto", "--json",
            tmp_path / "fit.json", "--quiet")
    assert r.returncode == 0, r.stderr
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert 1e-6 < fit["deadband"] < 2e-5 and fit["overflow"] == 0
    r = run("simulate", data, "--params", tmp_path / "fit.json", "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    assert "deadband: " in r.stdout
    sim = np.genfromtxt(tmp_path / "s.csv", delimiter=",", names=True)
    rmse = float(np.sqrt(np.mean((sim["F_modelN"] - F) ** 2)))
    assert abs(rmse - fit["rmse"]) <= 1e-6 * fit["rmse"]
