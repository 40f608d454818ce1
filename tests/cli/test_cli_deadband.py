"""`--deadband` of the commands: the default 'auto' plays a noisy standstill (no memory
overflow, the log says why) and leaves a clean file alone; without a deadband the overflow
is reported with what to do; the deadband used is saved and reused by ``simulate
--params``."""

import json

import numpy as np
import pytest

import jaxfric
from jaxfric import paper

from ..helpers import standstill_motion
from .test_cli import run


def test_simulate_default_plays_a_noisy_standstill_and_none_overflows(tmp_path):
    """The default ('auto') on a noisy standstill (three true reversals, a noisy velocity
    column as a robot logs it): no overflow, and the log names the deadband and why;
    ``--deadband none`` overflows and the warning says what to do."""
    t, x, x_true = standstill_motion(11)
    t, x, x_true = t[:4000], x[:4000], x_true[:4000]
    v = np.gradient(x_true, t) + 1e-3 * np.random.default_rng(5).standard_normal(t.size)
    data = tmp_path / "joint.csv"
    np.savetxt(data, np.column_stack([t, x, v]), delimiter=",", header="t[s],x[m],v[m/s]",
               comments="", fmt="%.17g")
    out = tmp_path / "sim.csv"
    played = run("simulate", data, "--stack-size", 4, "--out", out)
    assert played.returncode == 0, played.stderr
    assert "overflowed" not in played.stderr
    line = next(s for s in played.stdout.splitlines() if s.startswith("deadband: "))
    assert " m applied: " in line and "within the position noise band" in line, line
    raw = run("simulate", data, "--stack-size", 4, "--deadband", "none", "--out", out)
    assert raw.returncode == 0, raw.stderr
    assert "overflowed" in raw.stderr and "--stack-size" in raw.stderr
    assert "--deadband B" in raw.stderr
    bad = run("simulate", data, "--deadband", "wide", "--out", out)
    assert bad.returncode != 0 and "--deadband" in bad.stderr
    small = run("simulate", data, "--stack-size", 0, "--out", out)
    assert small.returncode != 0 and "--stack-size" in small.stderr


def test_simulate_default_leaves_a_clean_encoder_file_alone(tmp_path):
    """On a clean file quantised by its encoder the default applies nothing: the log says
    so, and the force is the one of ``--deadband none`` to the last bit."""
    from jaxfric.synthetic import measurement

    t, x, _ = measurement("gms_power", (), noise=0.03, dt=1e-2, seed=0)
    data = tmp_path / "clean.csv"
    np.savetxt(data, np.column_stack([t, x]), delimiter=",", header="t[s],x[m]",
               comments="", fmt="%.17g")
    auto = run("simulate", data, "--out", tmp_path / "auto.csv")
    assert auto.returncode == 0, auto.stderr
    assert "deadband: none needed (no reversal within the position noise band" in auto.stdout
    none = run("simulate", data, "--deadband", "none", "--out", tmp_path / "none.csv")
    assert none.returncode == 0, none.stderr
    assert (tmp_path / "auto.csv").read_text() == (tmp_path / "none.csv").read_text()


def test_fit_records_the_deadband_and_simulate_params_reuses_it(tmp_path):
    t, x, x_true = standstill_motion(12)
    t, x, x_true = t[:3000:2], x[:3000:2], x_true[:3000:2]
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x_true))
    data = tmp_path / "run.csv"
    np.savetxt(data, np.column_stack([t, x, F]), delimiter=",", header="t[s],x[m],F[N]",
               comments="", fmt="%.17g")
    r = run("fit", data, "--model", "tustin", "--json", tmp_path / "fit.json", "--quiet")
    assert r.returncode == 0, r.stderr  # the default: 'auto'
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


def test_deadband_default_is_auto_and_a_saved_result_keeps_its_own(tmp_path):
    """Every command's default is 'auto'; with ``--params`` the deadband saved in it (a
    result saved without one was played through none, as before 'auto' was the default)."""
    from fitting.cli._signals import _deadband_option
    from fitting.cli.main import build_parser

    parser = build_parser()
    for command in ("fit", "diagnose", "compare", "simulate"):
        given = parser.parse_args([command, "f.csv"]).deadband
        assert _deadband_option(given, None) == "auto", command
        assert parser.parse_args([command, "f.csv", "--deadband", "none"]).deadband == "none"
    saved, plain = tmp_path / "saved.json", tmp_path / "plain.json"
    saved.write_text(json.dumps({"deadband": 3e-6}))
    plain.write_text(json.dumps({"params": {}}))
    assert _deadband_option(None, saved) == 3e-6
    assert _deadband_option(None, plain) is None
    assert _deadband_option("auto", plain) == "auto"


def test_auto_on_a_clean_encoder_file_estimates_one_count_and_applies_none():
    """Why 'auto' decides before it plays: a clean file quantised by its encoder has a band
    of one count (not 0), and playing it would move the position; it has no reversal
    within that band, so `auto_deadband` applies nothing."""
    from jaxfric.motion import auto_deadband, deadband_choice, estimate_deadband, play
    from jaxfric.synthetic import ENCODER, measurement

    _, x, _ = measurement("gms_power", (), noise=0.03, dt=1e-2, seed=0)
    b = estimate_deadband(x)
    assert abs(b - ENCODER) < 1e-3 * ENCODER
    assert np.max(np.abs(np.asarray(play(x, b)) - x)) > 0.5 * ENCODER
    choice = deadband_choice(x)
    assert choice.deadband is None and choice.estimate == b and choice.reversals > 10
    assert auto_deadband(x) is None


def test_compare_records_the_deadband(tmp_path):
    data = _standstill_file(tmp_path)
    out = tmp_path / "cmp.json"
    r = run("compare", data, "--models", "tustin", "--max-steps", 20, "--deadband", "auto",
            "--json", out, "--quiet")
    assert r.returncode == 0, r.stderr
    res = json.loads(out.read_text())["models"]["tustin"]
    assert 1e-6 < res["deadband"] < 2e-5
    r = run("compare", data, "--models", "tustin", "--max-steps", 20, "--deadband", "none",
            "--json", out, "--quiet")
    assert r.returncode == 0, r.stderr
    assert "deadband" not in json.loads(out.read_text())["models"]["tustin"]


@pytest.mark.slow
def test_joints_fit_plays_each_joint_and_simulate_reuses_it(tmp_path):
    data = _standstill_file(tmp_path, columns=2)
    fit = tmp_path / "fit.json"
    r = run("fit", data, "--model", "tustin", "--json", fit, "--quiet")  # default: 'auto'
    assert r.returncode == 0, r.stderr
    joints = json.loads(fit.read_text())["joints"]
    b1, b2 = joints["joint 1"]["deadband"], joints["joint 2"]["deadband"]
    assert 1e-6 < b1 < 2e-5 and abs(b2 - 2 * b1) < 0.05 * b1  # joint 2 moves twice as far
    r = run("simulate", data, "--params", fit, "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("deadband: ") == 2
