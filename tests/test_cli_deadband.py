"""`jaxfric simulate --stack-size/--deadband`: memory overflow on noisy standstill is
reported with what to do, and the deadband ('auto': estimated from the positions) removes
it."""

import json

import numpy as np
import pytest

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


def _standstill_file(tmp_path, seed=13, columns=1):
    """A noisy-standstill file with Tustin friction: one joint (t, x, F) or `columns`
    joints in the wide layout (t, q1, tau1, q2, tau2 ...)."""
    t, x, x_true = standstill_motion(seed)
    t, x, x_true = t[:3000:2], x[:3000:2], x_true[:3000:2]
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x_true))
    data = tmp_path / "run.csv"
    if columns == 1:
        cols, header = [t, x, F], "t[s],x[m],F[N]"
    else:
        cols, header = [t], ["t[s]"]
        for i in range(1, columns + 1):
            cols += [x * i, F]
            header += [f"q{i}[rad]", f"tau{i}[N m]"]
        header = ",".join(header)
    np.savetxt(data, np.column_stack(cols), delimiter=",", header=header, comments="",
               fmt="%.17g")
    return data


def test_deadband_default_is_none_for_every_command():
    """The default stays none (benchmarks/deadband_default.py: on clean files the estimate
    is one encoder count, not 0, and it changes a two-state model's force by 0.3-1.3 % RMS
    and the tribometer's reversals; docs/algorithm.md section 1)."""
    from fitting.cli.main import build_parser

    parser = build_parser()
    for command in ("fit", "diagnose", "compare", "simulate"):
        assert parser.parse_args([command, "f.csv"]).deadband is None, command
        assert parser.parse_args([command, "f.csv", "--deadband", "auto"]).deadband == "auto"


def test_auto_estimate_on_a_clean_encoder_file_is_one_count():
    """Why the default is not 'auto': a clean file quantised by its encoder gets a deadband
    of one count (not 0), which moves the played position."""
    from jaxfric.motion import estimate_deadband, play
    from jaxfric.synthetic import ENCODER, measurement

    _, x, _ = measurement("gms_power", (), noise=0.03, dt=1e-2, seed=0)
    b = estimate_deadband(x)
    assert abs(b - ENCODER) < 1e-3 * ENCODER
    assert np.max(np.abs(np.asarray(play(x, b)) - x)) > 0.5 * ENCODER


def test_compare_records_the_deadband(tmp_path):
    data = _standstill_file(tmp_path)
    out = tmp_path / "cmp.json"
    r = run("compare", data, "--models", "tustin", "--max-steps", 20, "--deadband", "auto",
            "--json", out, "--quiet")
    assert r.returncode == 0, r.stderr
    res = json.loads(out.read_text())["models"]["tustin"]
    assert 1e-6 < res["deadband"] < 2e-5
    r = run("compare", data, "--models", "tustin", "--max-steps", 20, "--json", out, "--quiet")
    assert r.returncode == 0, r.stderr
    assert "deadband" not in json.loads(out.read_text())["models"]["tustin"]


@pytest.mark.slow
def test_joints_fit_plays_each_joint_and_simulate_reuses_it(tmp_path):
    data = _standstill_file(tmp_path, columns=2)
    fit = tmp_path / "fit.json"
    r = run("fit", data, "--model", "tustin", "--deadband", "auto", "--json", fit, "--quiet")
    assert r.returncode == 0, r.stderr
    joints = json.loads(fit.read_text())["joints"]
    b1, b2 = joints["joint 1"]["deadband"], joints["joint 2"]["deadband"]
    assert 1e-6 < b1 < 2e-5 and abs(b2 - 2 * b1) < 0.05 * b1  # joint 2 moves twice as far
    r = run("simulate", data, "--params", fit, "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("deadband: ") == 2
